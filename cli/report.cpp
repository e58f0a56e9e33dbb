// fogctl report: one self-contained HTML file (opens offline) with the temperature profile,
// measured against predicted drift, the residual with failing intervals shaded, the residual
// against the top candidates, the diagnosis, the lineage of the error and a qualification
// summary in the terms of IEEE Std 952. Plots are drawn by the vendored uPlot, inline.
#include <cmath>
#include <memory>
#include <ostream>
#include <sstream>

#include "fogbench/model/workbench.hpp"
#include "table.hpp"
#include "workbench.hpp"

namespace fogbench::cli {
namespace vendor {
extern const char* const kUplotVersion;
extern const char* const kUplotJs;
extern const char* const kUplotCss;
}  // namespace vendor

namespace wb = model::workbench;
using nlohmann::json;

namespace {

std::string esc(const std::string& s) {
  std::string o;
  for (char c : s) {
    switch (c) {
      case '<': o += "&lt;"; break;
      case '>': o += "&gt;"; break;
      case '&': o += "&amp;"; break;
      case '"': o += "&quot;"; break;
      default: o += c;
    }
  }
  return o;
}

// JSON inside a <script>: "</" would end the script element.
std::string script_json(const json& j) {
  std::string s = j.dump();
  std::string o;
  o.reserve(s.size());
  for (std::size_t i = 0; i < s.size(); ++i) {
    if (s[i] == '<' && i + 1 < s.size() && s[i + 1] == '/') o += "<\\";
    else o += s[i];
  }
  return o;
}

json pick(const std::vector<double>& v, const std::vector<std::size_t>& idx, int digits = 4) {
  json a = json::array();
  const double scale = std::pow(10.0, digits);
  for (std::size_t i : idx) {
    if (i >= v.size() || !std::isfinite(v[i])) a.push_back(nullptr);
    else a.push_back(std::round(v[i] * scale) / scale);  // fewer digits, smaller file
  }
  return a;
}

// Four significant digits: coefficients span 1e-4 (deg/h per degC^2) to 10 (deg/h per degC/min).
std::string sig(double v) {
  if (!std::isfinite(v)) return "-";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.4g", v);
  return buf;
}

std::string pct(double v) { return std::isfinite(v) ? fixed(100.0 * v, 1) + "%" : "-"; }

struct HtmlTable {
  std::string s = "<table>";
  explicit HtmlTable(const std::vector<std::string>& head) {
    s += "<tr>";
    for (const auto& h : head) s += "<th>" + esc(h) + "</th>";
    s += "</tr>";
  }
  void row(const std::vector<std::string>& cells, const std::string& cls = "") {
    s += cls.empty() ? "<tr>" : "<tr class=\"" + cls + "\">";
    // Words align left, numbers right (so that digits line up).
    for (const auto& c : cells) {
      const bool num = !c.empty() && c.find_first_not_of("0123456789+-.e%<> →") == std::string::npos;
      s += num ? "<td>" + esc(c) + "</td>" : "<td class=\"w\">" + esc(c) + "</td>";
    }
    s += "</tr>";
  }
  std::string str() const { return s + "</table>"; }
};

// The candidate's fitted contribution to the drift on a run: coef * term(t - lag), demeaned.
std::vector<double> contribution(const wb::Candidate& c, const model::RunData& run, double tref_c) {
  auto t = model::parse_term(c.expr);
  auto s = model::run_signals(run, tref_c);
  if (!t || !s) return {};
  auto x = model::evaluate(*t->expr, s->view());
  if (!x) return {};
  const std::size_t n = x->size(), lag = static_cast<std::size_t>(c.lag_s);
  std::vector<double> y(n);
  double m = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    y[i] = c.coef * (*x)[i >= lag ? i - lag : 0];
    m += y[i];
  }
  for (double& v : y) v -= m / static_cast<double>(n);
  return y;
}

constexpr const char* kStyle = R"css(
body{font-family:system-ui,-apple-system,"Segoe UI",sans-serif;margin:24px auto;max-width:1180px;color:#1d2430;padding:0 16px}
h1{font-size:1.5em;margin-bottom:4px}h2{font-size:1.2em;margin-top:32px;border-bottom:1px solid #d0d6de;padding-bottom:4px}
h3{font-size:1.02em;margin:18px 0 6px}.sub{color:#5a6472}
table{border-collapse:collapse;margin:8px 0 12px;font-size:.88em}th,td{padding:3px 9px;border-bottom:1px solid #e3e7ec;text-align:right}
th{background:#f3f5f8;text-align:center}td:first-child,th:first-child{text-align:left}
td.w{text-align:left}tr.hit td{background:#fff1e6;font-weight:600}tr.fail td{color:#b3261e}
.verdict{display:inline-block;padding:4px 12px;border-radius:4px;font-weight:700;color:#fff}
.pass{background:#2e7d32}.failv{background:#b3261e}.note{color:#5a6472;font-size:.88em;max-width:1000px}
.plot{margin:6px 0 14px}.summary{background:#f3f5f8;border-left:4px solid #3d6fb6;padding:8px 12px;max-width:1100px}
)css";

constexpr const char* kScript = R"js(
(function(){
  let drawn = 0;
  const W = () => Math.max(600, Math.min(1140, document.body.clientWidth - 40));
  const colors = ['#3d6fb6','#d9822b','#2e7d32','#8e44ad','#b3261e','#16a085'];
  // Failing intervals shaded behind the series: the plot's own coordinates, via a hook.
  function shade(intervals){
    return {hooks:{drawClear:[u=>{
      const ctx=u.ctx; ctx.save(); ctx.fillStyle='rgba(179,38,30,0.13)';
      for(const f of intervals){
        const x0=u.valToPos(f.start_s,'x',true), x1=u.valToPos(f.start_s+f.duration_s,'x',true);
        ctx.fillRect(x0,u.bbox.top,Math.max(1,x1-x0),u.bbox.height);
      }
      ctx.restore();}]}};
  }
  // styles[i]: {stroke, width, dash} of series i, else the palette.
  function plot(id, title, ylabel, names, cols, extra, styles){
    const el=document.getElementById(id); if(!el) return;
    const series=[{label:'time, s'}].concat(names.map((n,i)=>Object.assign({label:n,stroke:colors[i%colors.length],width:1.2,spanGaps:false},(styles||[])[i]||{})));
    const opts=Object.assign({title:title,width:W(),height:260,scales:{x:{time:false}},
      axes:[{label:'time, s'},{label:ylabel,size:70}],series:series,legend:{live:true}}, extra||{});
    new uPlot(opts, cols, el); drawn++;
  }
  for(const [k,r] of DATA.runs.entries()){
    const s=r.series, t=s.time_s;
    const temps=[['T1 (coil centre)',s.t1_c],['T2 (outer wall)',s.t2_c]];
    if(s.ta_c) temps.push(['Ta (chamber air)',s.ta_c]);
    plot('temp'+k, 'Temperature profile: '+r.run, 'degC', temps.map(x=>x[0]), [t].concat(temps.map(x=>x[1])));
    plot('drift'+k, 'Measured and predicted drift: '+r.run, 'deg/h', ['measured','predicted'], [t,s.measured_dph,s.predicted_dph],
         null, [{stroke:'#aab4c0',width:1},{stroke:'#d9822b',width:2}]);
    const lim={stroke:'#b3261e',width:1,dash:[6,4]};
    plot('resid'+k, 'Residual (measured - predicted), failing intervals shaded: '+r.run, 'deg/h',
         ['residual','residual, 61 s average','+k sigma_a','-k sigma_a'],
         [t,s.residual_dph,s.residual_smooth_dph,t.map(()=>r.threshold_dph),t.map(()=>-r.threshold_dph)], shade(r.failures),
         [{stroke:'#c3cad3',width:1},{stroke:'#1f4e8c',width:2},lim,lim]);
  }
  if(DATA.cand && DATA.cand.names.length){
    plot('cand','Residual on '+DATA.fit_run+' against the top candidates (each: its refitted contribution, mean removed)','deg/h',
         ['residual, 61 s average'].concat(DATA.cand.names), [DATA.cand.time_s,DATA.cand.residual].concat(DATA.cand.cols),
         null, [{stroke:'#8a949f',width:1}].concat(DATA.cand.cols.map((c,i)=>({stroke:colors[(i+1)%colors.length],width:2}))));
  }
  if(DATA.lineage && DATA.lineage.steps>1){
    const x=[...Array(DATA.lineage.steps).keys()];
    plot('lineage','Compensated std along the lineage (root = 0)','deg/h', DATA.lineage.runs, [x].concat(DATA.lineage.cols),
         {axes:[{label:'model in the lineage (0 = root)',incrs:[1,2,5,10],values:(u,v)=>v.map(x=>String(x))},{label:'deg/h',size:70}],
          scales:{x:{time:false},y:{range:(u,lo,hi)=>[0,hi*1.1]}}},
         DATA.lineage.runs.map(()=>({width:2,points:{show:true,size:7}})));
  }
  document.body.setAttribute('data-plots', String(drawn));
})();
)js";

}  // namespace

int run_report(const ReportOptions& o, std::ostream& out, std::ostream& err) {
  auto m = load_model(o.model);
  if (!m) {
    err << "fogctl report: " << m.error() << "\n";
    return kExitError;
  }
  if (!(o.threshold > 0.0 && o.threshold < 1.0)) {
    err << "fogctl report: --threshold must be between 0 and 1 (a ratio of std), got " << o.threshold << "\n";
    return kExitError;
  }
  std::vector<model::RunData> runs;
  for (const auto& p : o.runs) {
    auto r = load_run(p, o.input);
    if (!r) {
      err << "fogctl report: " << r.error() << "\n";
      return kExitError;
    }
    runs.push_back(std::move(*r));
  }
  const std::span<const model::RunData> held = std::span<const model::RunData>(runs).subspan(1);
  auto d = wb::diagnose(*m, runs.front(), held);
  if (!d) {
    err << "fogctl report: " << d.error().message << "\n";
    return kExitError;
  }
  // Every run but the first is independent of the fit (std::vector<bool> is not contiguous).
  const std::unique_ptr<bool[]> held_flags(new bool[runs.size()]);
  for (std::size_t i = 0; i < runs.size(); ++i) held_flags[i] = i > 0;
  const wb::Qualification q = wb::qualify(*m, runs, std::span<const bool>(held_flags.get(), runs.size()), o.threshold);
  const wb::Lineage lin = wb::lineage(*m, runs);

  json data = {{"fit_run", runs.front().name}, {"runs", json::array()}};
  std::string body;
  body += "<h1>fogbench report: model " + esc(m->terms_string()) + "</h1>";
  body += "<div class=\"sub\">" + esc(o.model) + " (" + std::string(to_string(m->method)) + " method, fitted on " +
          esc(m->fitted_on.name) + (m->created_at.empty() ? "" : ", " + esc(m->created_at)) + "); runs: ";
  for (std::size_t i = 0; i < runs.size(); ++i) body += (i ? ", " : "") + esc(runs[i].name) + (i ? " (held out)" : " (fit run)");
  body += "</div>";

  // Qualification summary.
  body += "<h2>Qualification summary (IEEE Std 952 thermal sensitivities)</h2>";
  body += std::string("<p><span class=\"verdict ") + (q.pass ? "pass\">PASS" : q.marginal ? "failv\">MARGINAL" : "failv\">FAIL") +
          "</span> compensated std under " + fixed(100.0 * q.threshold, 0) +
          "% of the raw std on every run, within 1.5 x the model's noise std and no failing interval of 60 s or more</p>";
  for (const auto& x : q.runs)
    for (const auto& why : x.reasons) body += "<p class=\"note\">" + esc(x.run) + ": " + esc(why) + "</p>";
  {
    HtmlTable t({"sensitivity", "term", "value", "1 sigma", "unit", "source"});
    t.row({"bias", "mu0", fixed(q.mu0_dph, 3), fixed(q.mu0_se_dph, 3), "deg/h", "the model"});
    // IEEE Std 952's three thermal sensitivities always appear: from the model when it has
    // the term, else from diagnose's refit of the model with it (so a missing one shows its size).
    const std::pair<const char*, const char*> ieee[] = {
        {"T1", "temperature (per degC)"}, {"d(T1)", "temperature rate (per degC/min)"}, {"grad", "temperature gradient (per degC)"}};
    std::vector<bool> shown(q.sensitivities.size(), false);
    for (const auto& [key, what] : ieee) {
      bool found = false;
      for (std::size_t i = 0; i < q.sensitivities.size(); ++i) {
        const auto& x = q.sensitivities[i];
        if (x.term.substr(0, x.term.find('@')) != key) continue;
        t.row({what, x.term, sig(x.coef), sig(x.se_in_unit), x.unit, "the model"});
        shown[i] = found = true;
      }
      if (found) continue;
      for (const auto& c : d->candidates)
        if (c.expr == key && c.evaluated) {
          t.row({what, c.term, sig(c.coef), sig(c.se_dph_per_unit), c.unit, std::string("refit with it (not in the model") + (c.detected ? ", detected)" : ", not needed)")});
          found = true;
        }
      if (!found) t.row({what, key, "-", "-", "", "not estimated"});
    }
    for (std::size_t i = 0; i < q.sensitivities.size(); ++i)
      if (!shown[i]) {
        const auto& x = q.sensitivities[i];
        t.row({"other", x.term, sig(x.coef), sig(x.se_in_unit), x.unit, "the model"});
      }
    body += t.str();
    HtmlTable r({"run", "role", "raw std, deg/h", "compensated std, deg/h", "comp/raw", "heating - cooling at equal T1, deg/h", "the same compensated, deg/h",
                 "peak excursion on ramps, deg/h", "verdict"});
    for (const auto& x : q.runs)
      r.row({x.run, x.held_out ? "independent" : "fit", fixed(x.meas_std_dph, 3), fixed(x.comp_std_dph, 3), pct(x.ratio),
             fixed(x.hysteresis_dph, 3), fixed(x.hysteresis_comp_dph, 3), fixed(x.peak_ramp_excursion_dph, 3),
             x.pass ? "pass" : x.verdict == model::Verdict::marginal ? "MARGINAL" : "FAIL"},
            x.pass ? "" : "fail");
    body += r.str();
    body += "<p class=\"note\">Heating minus cooling: mean output in 1 degC bins of T1 visited by both heating and cooling "
            "(at least 30 s each), weighted by the fewer samples. Peak excursion: largest |61 s average of the output - mu0| "
            "during ramps. Sensitivities: the model's coefficients with their standard errors from the prewhitened regression.</p>";
  }

  // Diagnosis.
  body += "<h2>Diagnosis</h2><div class=\"summary\">" + esc(d->summary) + "</div>";
  {
    std::vector<std::string> head{"#", "term", "effect", "lag, s", "rms fit, deg/h", "fall", "delta BIC", "p"};
    for (const auto& h : d->held_out_runs) head.push_back("rms " + h);
    head.push_back("verdict");
    HtmlTable t(head);
    int rank = 0;
    for (const auto& c : d->candidates) {
      if (!c.evaluated) continue;
      std::vector<std::string> row{std::to_string(++rank), c.term, c.effect, std::to_string(c.lag_s),
                                   fixed(c.rms_before_dph, 3) + " → " + fixed(c.rms_after_dph, 3), pct(c.fall), fixed(c.delta_bic, 1),
                                   c.p_value < 1e-4 ? "<1e-4" : fixed(c.p_value, 4)};
      for (const auto& h : c.held_out) row.push_back(h.scored ? fixed(h.rms_before_dph, 3) + " → " + fixed(h.rms_after_dph, 3) : "skipped");
      row.push_back(!c.detected ? "-" : rank == 1 ? "MISSING" : "helps too");
      t.row(row, rank == 1 && c.detected ? "hit" : "");
    }
    body += t.str();
    std::string notes;
    for (const auto& c : d->candidates)
      if (!c.evaluated) notes += "<li>" + esc(c.term) + ": " + esc(c.skipped) + "</li>";
    if (!notes.empty()) body += "<p class=\"note\">Skipped:</p><ul class=\"note\">" + notes + "</ul>";
    if (!d->candidates.empty() && d->candidates.front().detected)
      body += "<p class=\"note\"><b>Why " + esc(d->candidates.front().expr) + ":</b> " + esc(d->candidates.front().explanation) + "</p>";
    body += "<p class=\"note\">Rule: " + esc(d->rule) + ".</p>";
    HtmlTable c({"coefficient", "value", "1 sigma", "unit"});
    for (const auto& x : d->coefs) c.row({x.term, sig(x.coef), sig(x.se_in_unit), x.unit});
    body += "<h3>Coefficients of the model refitted on " + esc(d->fit_run) + "</h3>" + c.str();
    for (const auto& p : d->collinear_coefs)
      body += "<p class=\"note\">Collinear: " + esc(p.a) + " and " + esc(p.b) + " (r = " + fixed(p.r, 3) + "): " + esc(p.why) + "</p>";
    const auto& w = d->whiteness;
    body += "<p class=\"note\">Residual prewhitened by the model's AR filter: Ljung-Box Q " + fixed(w.lb.q, 1) + " on " +
            std::to_string(w.lb.dof) + " dof, p " + fixed(w.lb.p_value, 4) + (w.white() ? " (white)" : " (not white)") + ".</p>";
    HtmlTable x({"regressor", "peak cross-correlation", "at lag, s", "lags outside ±2/√N"});
    for (const auto& cc : d->ccf)
      x.row({cc.term, fixed(cc.peak_r, 3), std::to_string(cc.peak_lag_s), std::to_string(cc.outside) + " of " + std::to_string(cc.r.size())});
    body += "<h3>Cross-correlation of the prewhitened residual with each regressor</h3>" + x.str();
  }

  // The residual against the top candidates on the fit run.
  {
    auto c0 = wb::compare(*m, runs.front());
    json cand = {{"names", json::array()}, {"cols", json::array()}};
    if (c0) {
      const auto idx = wb::decimate_indices(c0->residual_smooth_dph, o.max_points);
      cand["time_s"] = pick(c0->time_s, idx, 1);
      cand["residual"] = pick(c0->residual_smooth_dph, idx);
      int k = 0;
      for (const auto& c : d->candidates) {
        if (!c.evaluated || k >= 3) continue;
        auto y = contribution(c, runs.front(), m->tref_c);
        if (y.empty()) continue;
        cand["names"].push_back(c.term + " × " + fixed(c.coef, 4));
        cand["cols"].push_back(pick(y, idx));
        ++k;
      }
    }
    data["cand"] = cand;
    body += "<h2>Residual against the top candidates</h2><div class=\"plot\" id=\"cand\"></div>";
  }

  // Lineage.
  body += "<h2>Lineage of the error</h2>";
  {
    std::vector<std::string> head{"#", "terms"};
    for (const auto& r : lin.runs) head.push_back(r + ", deg/h");
    head.push_back("note");
    HtmlTable t(head);
    json cols = json::array();
    for (std::size_t r = 0; r < lin.runs.size(); ++r) cols.push_back(json::array());
    for (std::size_t i = 0; i < lin.steps.size(); ++i) {
      const auto& s = lin.steps[i];
      std::vector<std::string> row{std::to_string(i), s.terms};
      for (std::size_t r = 0; r < s.comp_std_dph.size(); ++r) {
        row.push_back(fixed(s.comp_std_dph[r], 3));
        cols[r].push_back(std::isfinite(s.comp_std_dph[r]) ? json(s.comp_std_dph[r]) : json(nullptr));
      }
      row.push_back(s.note);
      t.row(row);
    }
    body += t.str();
    data["lineage"] = {{"steps", lin.steps.size()}, {"runs", lin.runs}, {"cols", cols}};
    if (lin.steps.size() > 1) body += "<div class=\"plot\" id=\"lineage\"></div>";
  }

  // Per run: profile, drift, residual.
  for (std::size_t k = 0; k < runs.size(); ++k) {
    auto c = wb::compare(*m, runs[k]);
    if (!c) {
      err << "fogctl report: " << c.error().message << "\n";
      return kExitError;
    }
    const auto idx = wb::decimate_indices(c->residual_dph, o.max_points);
    json s = {{"time_s", pick(c->time_s, idx, 1)},
              {"measured_dph", pick(c->measured_dph, idx)},
              {"predicted_dph", pick(c->predicted_dph, idx)},
              {"residual_dph", pick(c->residual_dph, idx)},
              {"residual_smooth_dph", pick(c->residual_smooth_dph, idx)},
              {"t1_c", pick(c->t1_c, idx, 3)},
              {"t2_c", pick(c->t2_c, idx, 3)}};
    if (!c->ta_c.empty()) s["ta_c"] = pick(c->ta_c, idx, 3);
    json fails = json::array();
    for (const auto& f : c->failures) fails.push_back(wb::to_json(f));
    data["runs"].push_back({{"run", runs[k].name}, {"series", s}, {"threshold_dph", c->threshold_dph}, {"failures", fails}});
    const auto& v = c->verification;
    body += "<h2>Run " + esc(runs[k].name) + (k ? " (held out)" : " (fit run)") + "</h2>";
    body += "<p class=\"note\">" + std::to_string(v.run.n) + " samples; raw std " + fixed(v.run.meas_std, 3) + " deg/h, compensated " +
            fixed(v.run.comp_std, 3) + " deg/h (" + pct(v.run.ratio) + "); " + std::to_string(c->failures.size()) +
            " failing interval(s) beyond " + fixed(c->threshold_dph, 3) + " deg/h. Plotted: " + std::to_string(idx.size()) +
            " of " + std::to_string(runs[k].size()) + " samples (minimum and maximum of each bucket).</p>";
    body += "<div class=\"plot\" id=\"temp" + std::to_string(k) + "\"></div><div class=\"plot\" id=\"drift" + std::to_string(k) +
            "\"></div><div class=\"plot\" id=\"resid" + std::to_string(k) + "\"></div>";
    HtmlTable t({"part", "samples", "est mean", "meas mean", "est std", "meas std", "comp std", "comp/raw"});
    auto row = [&](const std::string& name, const model::Table1& x) {
      t.row({name, std::to_string(x.n), fixed(x.est_mean, 3), fixed(x.meas_mean, 3), fixed(x.est_std, 3), fixed(x.meas_std, 3),
             fixed(x.comp_std, 3), pct(x.ratio)});
    };
    row("whole run", v.run);
    for (const auto& p : v.phases) row(std::string(to_string(p.phase)), p.stats);
    for (const auto& st : c->steps) row("step " + std::to_string(st.step) + " (" + std::string(to_string(st.phase)) + ")", st.stats);
    body += t.str();
    if (!c->failures.empty()) {
      HtmlTable f({"phase", "step", "start, s", "duration, s", "mean error, deg/h", "peak error, deg/h", "T1, degC", "T2, degC",
                   "dT1/dt, degC/min", "grad, degC"});
      for (const auto& x : c->failures)
        f.row({std::string(to_string(x.phase)), x.step < 0 ? "-" : std::to_string(x.step), fixed(x.start_s, 0), fixed(x.duration_s, 0),
               fixed(x.mean_err_dph, 3), fixed(x.peak_err_dph, 3), fixed(x.t1_c, 2), fixed(x.t2_c, 2), fixed(x.rate_c_per_min, 3),
               fixed(x.grad_c, 3)});
      body += "<h3>Where the model fails</h3>" + f.str();
    }
  }
  body += std::string("<p class=\"note\">Plots: uPlot ") + vendor::kUplotVersion + " (MIT), embedded. Generated by fogctl " FOGBENCH_VERSION ".</p>";

  std::string html = "<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\"><title>fogbench report: " + esc(m->terms_string()) +
                     "</title><style>" + std::string(vendor::kUplotCss) + "</style><style>" + kStyle + "</style></head><body>" + body +
                     "<script>" + std::string(vendor::kUplotJs) + "</script><script>const DATA=" + script_json(data) + ";</script><script>" +
                     kScript + "</script></body></html>\n";
  if (auto w = write_text(o.output, html); !w) {
    err << "fogctl report: " << w.error() << "\n";
    return kExitError;
  }
  out << "report written to " << o.output << " (" << html.size() / 1024 << " KiB; " << (d->adequate ? "model adequate" : "missing effect: " + d->candidates.front().term)
      << "; qualification " << (q.pass ? "PASS" : q.marginal ? "MARGINAL" : "FAIL") << ")\n";
  return kExitOk;
}

}  // namespace fogbench::cli
