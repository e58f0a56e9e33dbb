// The report's plots: robust y-limits, printed legends, temperature loops, and the script that
// draws each plot specification with the vendored uPlot (report.cpp embeds it).
#include "report_plots.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include "fogbench/model/workbench.hpp"
#include "html.hpp"

namespace fogbench::cli::plots {

using nlohmann::json;

namespace {

std::string g3(double v) {
  if (!std::isfinite(v)) return "-";
  char b[32];
  std::snprintf(b, sizeof b, "%.3g", v);
  return b;
}

// Four significant digits: a plot is 1000 pixels high at most, and the file is smaller.
json num(double v) {
  if (!std::isfinite(v)) return nullptr;
  if (v == 0.0) return 0.0;
  const double e = std::floor(std::log10(std::abs(v)));
  const double scale = std::pow(10.0, 3.0 - e);
  return std::round(v * scale) / scale;
}

json pick(const std::vector<double>& v, const std::vector<std::size_t>& idx) {
  json a = json::array();
  for (std::size_t i : idx) a.push_back(i < v.size() ? num(v[i]) : json(nullptr));
  return a;
}

std::vector<std::size_t> all_indices(std::size_t n) {
  std::vector<std::size_t> idx(n);
  for (std::size_t i = 0; i < n; ++i) idx[i] = i;
  return idx;
}

std::vector<std::size_t> decimate(const std::vector<double>& y, std::size_t max_points) {
  if (y.size() <= max_points) return all_indices(y.size());
  return model::workbench::decimate_indices(y, max_points);
}

}  // namespace

YLimits robust_limits(const std::vector<std::span<const double>>& series, std::span<const double> always, double tail, double fence,
                      double margin) {
  std::vector<double> v;
  for (const auto& s : series)
    for (double x : s)
      if (std::isfinite(x)) v.push_back(x);
  std::sort(v.begin(), v.end());
  YLimits l;
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  if (!v.empty()) {
    double f_lo = v.front(), f_hi = v.back();
    const std::size_t n = v.size();
    if (n >= 3) {
      const double last = static_cast<double>(n - 1);
      const auto ilo = std::min(n - 1, static_cast<std::size_t>(std::ceil(tail * last)));
      const auto ihi = std::max(ilo, static_cast<std::size_t>(std::floor((1.0 - tail) * last)));
      const double q_lo = v[ilo], q_hi = v[ihi];
      // A series nearly constant but for an outlier has w = 0: a floor keeps the fence finite.
      const double w = std::max(q_hi - q_lo, 1e-9 * std::max(1.0, std::max(std::abs(q_lo), std::abs(q_hi))));
      f_lo = q_lo - fence * w;
      f_hi = q_hi + fence * w;
    }
    for (double x : v)
      if (x >= f_lo && x <= f_hi) {
        lo = std::min(lo, x);
        hi = std::max(hi, x);
      }
  }
  for (double x : always)
    if (std::isfinite(x)) {
      lo = std::min(lo, x);
      hi = std::max(hi, x);
    }
  if (!(lo <= hi)) return l;  // nothing finite: -1..1
  double span = hi - lo;
  if (!(span > 0.0)) span = std::max(std::abs(hi), 1.0) * 0.2;
  l.lo = lo - margin * span;
  l.hi = hi + margin * span;
  for (double x : v) {
    if (x < l.lo) ++l.below;
    if (x > l.hi) ++l.above;
  }
  return l;
}

Keys keys(std::span<const double> y) {
  Keys k;
  double s = 0.0;
  for (double v : y)
    if (std::isfinite(v)) {
      if (k.n == 0) k.min = k.max = v;
      k.min = std::min(k.min, v);
      k.max = std::max(k.max, v);
      k.last = v;
      s += v;
      ++k.n;
    }
  if (k.n == 0) return k;
  k.mean = s / static_cast<double>(k.n);
  double ss = 0.0;
  for (double v : y)
    if (std::isfinite(v)) ss += (v - k.mean) * (v - k.mean);
  k.std = k.n > 1 ? std::sqrt(ss / static_cast<double>(k.n - 1)) : 0.0;
  return k;
}

std::string keys_text(const Keys& k, const std::string& unit) {
  if (k.n == 0) return "no finite sample";
  return "mean " + g3(k.mean) + ", std " + g3(k.std) + ", min " + g3(k.min) + ", max " + g3(k.max) + ", last " + g3(k.last) + " " + unit;
}

Loop split_by_direction(std::span<const double> t1_c, std::span<const double> y, int half_window, double min_rise_c) {
  Loop l;
  const std::size_t n = std::min(t1_c.size(), y.size());
  const auto h = static_cast<std::size_t>(std::max(1, half_window));
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (auto* v : {&l.heat_x, &l.heat_y, &l.cool_x, &l.cool_y, &l.hold_x, &l.hold_y}) v->assign(n, nan);
  for (std::size_t t = 0; t < n; ++t) {
    const std::size_t a = t >= h ? t - h : 0, b = std::min(n - 1, t + h);
    const double rise = t1_c[b] - t1_c[a];
    std::vector<double>* x = rise > min_rise_c ? &l.heat_x : rise < -min_rise_c ? &l.cool_x : &l.hold_x;
    std::vector<double>* yy = rise > min_rise_c ? &l.heat_y : rise < -min_rise_c ? &l.cool_y : &l.hold_y;
    (*x)[t] = t1_c[t];
    (*yy)[t] = y[t];
  }
  return l;
}

std::string render(const Plot& p, json& specs, std::size_t max_points) {
  json spec = {{"id", p.id}, {"kind", p.kind}, {"xlabel", p.xlabel}, {"ylabel", p.ylabel}, {"yzero", p.y_from_zero}, {"log", p.log},
               {"xnames", p.x_names}, {"failures", p.failures}, {"series", json::array()}};
  std::string title = p.title;
  if (p.robust) {
    std::vector<std::span<const double>> ys;
    std::vector<double> always = p.always;
    for (const auto& s : p.series) {
      if (s.robust) ys.emplace_back(s.y);
      else always.insert(always.end(), s.y.begin(), s.y.end());
    }
    const YLimits l = robust_limits(ys, always);
    spec["ylim"] = {l.lo, l.hi};
    if (l.outside())
      title += " [" + std::to_string(l.outside()) + " sample" + (l.outside() == 1 ? "" : "s") +
               " beyond the y-range, marked at the edge]";
  } else {
    spec["ylim"] = nullptr;
  }
  spec["title"] = title;
  std::vector<std::size_t> idx;
  if (p.kind == "time") {
    const Series* ref = p.series.empty() ? nullptr : &p.series.front();
    idx = ref ? decimate(ref->y, max_points) : std::vector<std::size_t>{};
    spec["x"] = pick(p.x, idx);
  } else if (p.kind != "xy") {
    idx = all_indices(p.x.size());
    spec["x"] = pick(p.x, idx);
  }
  std::string legend = "<div class=\"keys\" data-for=\"" + html_escape(p.id) + "\"><div class=\"keyt\">" + html_escape(title) + "</div>";
  for (const auto& s : p.series) {
    json js = {{"label", s.name}, {"stroke", s.stroke}, {"width", s.width}, {"dash", s.dash}, {"points", s.points}, {"line", s.line}};
    const bool constant = !s.y.empty() && std::all_of(s.y.begin(), s.y.end(), [&](double v) { return v == s.y.front(); });
    if (constant && p.kind != "xy") {
      js["const"] = num(s.y.front());  // a limit line: the page repeats it (no column of equal numbers)
    } else if (p.kind == "xy") {
      // Every k-th sample: in time order, so a loop's line stays a line (a series with NaN
      // gaps would defeat the min-max buckets).
      std::vector<std::size_t> sidx;
      const std::size_t step = max_points ? (s.y.size() + max_points - 1) / max_points : 1;
      for (std::size_t i = 0; i < s.y.size(); i += std::max<std::size_t>(1, step)) sidx.push_back(i);
      // Samples that belong to another series (NaN) become one gap, not a run of nulls.
      json xs = json::array(), ys = json::array();
      for (std::size_t i : sidx) {
        const json xv = i < s.x.size() ? num(s.x[i]) : json(nullptr), yv = num(s.y[i]);
        if ((xv.is_null() || yv.is_null()) && (ys.empty() || ys.back().is_null())) continue;
        xs.push_back(xv.is_null() || yv.is_null() ? json(nullptr) : xv);
        ys.push_back(xv.is_null() || yv.is_null() ? json(nullptr) : yv);
      }
      js["x"] = xs;
      js["y"] = ys;
    } else {
      js["y"] = pick(s.y, idx);
    }
    spec["series"].push_back(js);
    if (!s.keys.empty())
      legend += "<div class=\"key\"><i style=\"background:" + html_escape(s.stroke) + "\"></i><b>" + html_escape(s.name) + "</b>: " + html_escape(s.keys) + "</div>";
  }
  for (std::size_t i = 0; i < p.x_names.size(); ++i)
    legend += "<div class=\"key\">step " + std::to_string(i) + ": " + html_escape(p.x_names[i]) + "</div>";
  legend += "</div>";
  specs.push_back(spec);
  return "<div class=\"plot\" id=\"" + html_escape(p.id) + "\"></div>" + legend;
}

const char* const kPlotStyle = R"css(
.keys{display:none}
@media print{
  body{max-width:none;margin:0;padding:0 6mm}
  .uplot .u-legend{display:none}
  .keys{display:block;font-size:8.5pt;margin:0 0 10px;break-inside:avoid}
  .keys .keyt{display:none}
  .keys .key{margin:1px 0}
  .keys i{display:inline-block;width:14px;height:3px;margin:0 6px 3px 0;vertical-align:middle;-webkit-print-color-adjust:exact;print-color-adjust:exact}
  .plot{break-inside:avoid}
  h2{break-after:avoid}
}
)css";

const char* const kPlotScript = R"js(
(function(){
  let drawn = 0;
  const W = () => Math.max(600, Math.min(1140, document.body.clientWidth - 40));
  // Failing intervals shaded behind the series, in the plot's own coordinates.
  function shade(intervals){
    return u=>{
      const ctx=u.ctx; ctx.save(); ctx.fillStyle='rgba(179,38,30,0.13)';
      for(const f of intervals){
        const x0=u.valToPos(f.start_s,'x',true), x1=u.valToPos(f.start_s+f.duration_s,'x',true);
        ctx.fillRect(x0,u.bbox.top,Math.max(1,x1-x0),u.bbox.height);
      }
      ctx.restore();};
  }
  // Samples beyond the robust y-range: a triangle at the top or bottom edge, in the series' colour.
  function edges(spec){
    return u=>{
      const [lo,hi]=spec.ylim, ctx=u.ctx, r=4*devicePixelRatio;
      ctx.save();
      spec.series.forEach((s,i)=>{
        if(!u.series[i+1].show) return;
        const xs=spec.kind==='xy'?s.x:spec.x;
        ctx.fillStyle=s.stroke;
        for(let j=0;j<s.y.length;j++){
          const v=s.y[j]; if(v==null||xs[j]==null||(v>=lo&&v<=hi)) continue;
          const x=u.valToPos(xs[j],'x',true), up=v>hi, y=up?u.bbox.top+r:u.bbox.top+u.bbox.height-r;
          ctx.beginPath(); ctx.moveTo(x,up?y-r:y+r); ctx.lineTo(x-r,up?y+r:y-r); ctx.lineTo(x+r,up?y+r:y-r); ctx.closePath(); ctx.fill();
        }
      });
      ctx.restore();};
  }
  // The plot's ink, for tests and for people who wonder: coloured pixels (not the grey grid
  // and axes) inside the plotting area, in the element's data-ink after each draw.
  function ink(el){
    return u=>{
      const b=u.bbox, d=u.ctx.getImageData(b.left,b.top,Math.max(1,b.width),Math.max(1,b.height)).data;
      let n=0;
      for(let i=0;i<d.length;i+=4){
        const mx=Math.max(d[i],d[i+1],d[i+2]), mn=Math.min(d[i],d[i+1],d[i+2]);
        if(d[i+3]>0&&mx-mn>40) n++;
      }
      el.setAttribute('data-ink',String(n));};
  }
  // A scatter (mode 2): a dot per sample, filled in the series' colour.
  function dots(size){
    return (u,si)=>{
      const d=u.data[si], p=new Path2D(), r=size*devicePixelRatio/2;
      for(let i=0;i<d[0].length;i++){
        if(d[0][i]==null||d[1][i]==null) continue;
        const cx=u.valToPos(d[0][i],'x',true), cy=u.valToPos(d[1][i],'y',true);
        p.moveTo(cx+r,cy); p.arc(cx,cy,r,0,2*Math.PI);
      }
      return {stroke:null,fill:p};};
  }
  // A line through an xy series in time order, broken at nulls (uPlot's own line builders
  // window the data by x, which assumes x sorted: a loop is not).
  function polyline(u,si){
    const d=u.data[si], p=new Path2D();
    let pen=false;
    for(let i=0;i<d[0].length;i++){
      if(d[0][i]==null||d[1][i]==null){ pen=false; continue; }
      const x=u.valToPos(d[0][i],'x',true), y=u.valToPos(d[1][i],'y',true);
      if(pen) p.lineTo(x,y); else p.moveTo(x,y);
      pen=true;
    }
    return {stroke:p,fill:null};
  }
  function draw(spec){
    const el=document.getElementById(spec.id); if(!el) return;
    const xy=spec.kind==='xy';
    const x0={label:spec.xlabel};
    if(spec.kind==='step') x0.value=(u,v)=>v==null?'--':'step '+v+': '+(spec.xnames[v]||'');
    const series=[x0].concat(spec.series.map(s=>{
      const o={label:s.label,stroke:s.stroke,width:s.width,spanGaps:false};
      if(s.dash&&s.dash.length) o.dash=s.dash;
      if(!s.line&&xy){ o.paths=dots(3); o.fill=s.stroke; o.points={show:false}; return o; }
      if(xy){ o.paths=polyline; o.points={show:false}; return o; }
      if(!s.line) o.paths=()=>null;
      o.points=s.points?{show:true,size:6,fill:s.stroke,stroke:s.stroke}:{show:false};
      return o;
    }));
    const scales={x:{time:false}};
    if(spec.log){ scales.x.distr=3; scales.x.log=10; scales.y={distr:3,log:10}; }
    if(spec.ylim) scales.y={range:()=>spec.ylim};
    else if(spec.yzero) scales.y={range:(u,lo,hi)=>[0,hi*1.1]};
    const xaxis={label:spec.xlabel};
    if(spec.kind==='step') Object.assign(xaxis,{incrs:[1,2,5,10],values:(u,v)=>v.map(x=>Number.isInteger(x)?String(x):'')});
    const hooks={draw:[]};
    if(spec.failures&&spec.failures.length) hooks.drawClear=[shade(spec.failures)];
    if(spec.ylim) hooks.draw.push(edges(spec));
    hooks.draw.push(ink(el));
    const opts={title:spec.title,width:W(),height:260,scales:scales,axes:[xaxis,{label:spec.ylabel,size:70}],series:series,hooks:hooks,
                legend:{live:!xy}};
    if(xy) opts.mode=2;
    const data=xy?[null].concat(spec.series.map(s=>[s.x,s.y])):[spec.x].concat(spec.series.map(s=>s.y));
    new uPlot(opts, data, el); drawn++;
  }
  for(const spec of DATA.plots) for(const s of spec.series) if(s.const!==undefined) s.y=spec.x.map(()=>s.const);
  for(const spec of DATA.plots){
    try{ draw(spec); }catch(e){ console.error('plot '+spec.id+': '+e); }
  }
  document.body.setAttribute('data-plots', String(drawn));
})();
)js";

}  // namespace fogbench::cli::plots
