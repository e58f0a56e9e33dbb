// fogctl fleet spc --html (fleet_html.hpp).
#include "fleet_html.hpp"
#include "fleet_pchart.hpp"
#include "html.hpp"

#include <cmath>
#include <cstdio>
#include <ctime>
#include <optional>

#include "fogbench/model/terms.hpp"

namespace fogbench::cli {
namespace vendor {
extern const char* const kUplotJs;
extern const char* const kUplotCss;
}  // namespace vendor

namespace {

// JSON inside a <script>: "</" would end it.
std::string script_json(const nlohmann::json& j) {
  std::string s = j.dump();
  std::string out;
  for (std::size_t i = 0; i < s.size(); ++i) {
    if (s[i] == '<' && i + 1 < s.size() && s[i + 1] == '/') out += "<\\/", ++i;
    else out += s[i];
  }
  return out;
}

// Each figure: the individuals chart against the runs' end dates (a unit's index where a value has
// no date), the figure's unit on the y axis, every Western Electric signal marked by its rule
// (rule 1 red, 2 orange, 3 purple, 4 brown; the moving range's on its own chart), each value's
// point drawn below 400 values and a line above (the signals always marked), then the lots'
// means with their limits, one point per lot.
constexpr const char* kDraw = R"js(
const RULE_COLOURS = {1: '#d62728', 2: '#ff7f0e', 3: '#9467bd', 4: '#8c564b', 5: '#d62728'};
for (const [i, c] of DATA.entries()) {
  const host = document.getElementById('chart' + i), mrHost = document.getElementById('mr' + i);
  const n = c.x.length;
  const dated = c.t.every(v => v !== null);
  const xs = dated ? c.t : Array.from({length: n}, (_, k) => k + 1);
  const flat = v => xs.map(() => v);
  const w = Math.min(1100, window.innerWidth - 40);
  const xAxis = {label: dated ? 'run end (UTC)' : 'unit, in the order the runs ended'};
  const yAxis = {label: c.name + (c.unit ? ', ' + c.unit : ''), size: 70};
  const series = [{label: dated ? 'run end' : 'unit'}, {label: c.name, stroke: '#1f77b4', width: 1, points: {show: n < 400}},
                  {label: 'centre', stroke: '#2ca02c', dash: [6, 4]}, {label: 'UCL', stroke: '#d62728'},
                  {label: 'LCL', stroke: '#d62728'}];
  const data = [xs, c.x, flat(c.center), flat(c.ucl), flat(c.lcl)];
  for (const rule of [1, 2, 3, 4]) {
    const marked = c.x.map(() => null);
    for (const s of c.signals) if (s.rule === rule) for (let k = s.first; k <= s.index; ++k) marked[k] = c.x[k];
    if (!marked.some(v => v !== null)) continue;
    series.push({label: 'rule ' + rule, stroke: 'transparent',
                 points: {show: true, size: rule === 1 ? 9 : 7, fill: RULE_COLOURS[rule], stroke: RULE_COLOURS[rule]}});
    data.push(marked);
  }
  new uPlot({title: c.name + ': individuals', width: w, height: 300, scales: {x: {time: dated}},
             axes: [xAxis, yAxis], series: series}, data, host);
  const mrMarked = c.x.map(() => null);
  for (const s of c.signals) if (s.rule === 5) mrMarked[s.index] = c.mr[s.index];
  new uPlot({title: c.name + ': moving range', width: w, height: 200, scales: {x: {time: dated}},
             axes: [xAxis, {label: 'moving range' + (c.unit ? ', ' + c.unit : ''), size: 70}],
             series: [{label: dated ? 'run end' : 'unit'}, {label: 'MR', stroke: '#7f7f7f', width: 1},
                      {label: 'MRbar', stroke: '#2ca02c', dash: [6, 4]}, {label: 'UCL', stroke: '#d62728'},
                      {label: 'moving range signal', stroke: 'transparent', points: {show: true, size: 8, fill: '#d62728'}}]},
    [xs, c.mr, flat(c.mr_bar), flat(c.mr_ucl), mrMarked], mrHost);
  if (c.lots.length > 0) {
    const li = c.lots.map((_, k) => k + 1);
    new uPlot({title: c.name + ': lot means (lot ' + c.lots.map(l => l.lot).join(', ') + ')', width: w, height: 240,
               scales: {x: {time: false}},
               axes: [{label: 'lot (1 = ' + c.lots[0].lot + '; the table below names each)'}, {label: 'lot mean' + (c.unit ? ', ' + c.unit : ''), size: 70}],
               series: [{label: 'lot'}, {label: 'lot mean', stroke: '#1f77b4', width: 0, points: {show: true, size: 8}},
                        {label: 'lot UCL', stroke: '#d62728', dash: [3, 3]}, {label: 'lot LCL', stroke: '#d62728', dash: [3, 3]},
                        {label: 'lot out of limits', stroke: 'transparent', points: {show: true, size: 11, fill: '#d62728'}}]},
      [li, c.lots.map(l => l.mean), c.lots.map(l => l.ucl), c.lots.map(l => l.lcl), c.lots.map(l => l.side !== 0 ? l.mean : null)],
      document.getElementById('lots' + i));
  }
}
)js";

constexpr const char* kStyle =
    "body{font-family:system-ui,sans-serif;margin:20px;color:#222}h1{font-size:22px}h2{font-size:17px;margin-top:28px}"
    "table{border-collapse:collapse;font-size:13px}td,th{border:1px solid #ccc;padding:2px 6px;text-align:left}"
    ".note{color:#555;font-size:13px}.pchart td.out{color:#d62728;font-weight:bold;background:#fde8e8}";

// The unit of a figure stored by the plant: a model coefficient's from the term language
// (d(T1): deg/h per degC/min), the noise and the compensated std in deg/h, the ratio none.
std::string figure_unit(const std::string& name) {
  if (name == "mu0" || name == "sigma_a" || name == "comp_std" || name == "raw_std" || name.ends_with("_dph")) return "deg/h";
  if (name == "ratio" || name == "comp_raw") return "ratio";
  if (auto t = model::parse_term(name); t && t->expr) return model::coef_unit(*t->expr);
  return "";
}

// An ISO 8601 UTC time (2026-01-01T00:00:00Z, or with a space) as seconds since 1970.
std::optional<double> epoch_of(const std::string& iso) {
  std::tm tm{};
  int y = 0, mo = 0, d = 0, h = 0, mi = 0;
  double sec = 0;
  if (std::sscanf(iso.c_str(), "%d-%d-%d%*c%d:%d:%lf", &y, &mo, &d, &h, &mi, &sec) != 6) return std::nullopt;
  tm.tm_year = y - 1900;
  tm.tm_mon = mo - 1;
  tm.tm_mday = d;
  tm.tm_hour = h;
  tm.tm_min = mi;
  return static_cast<double>(::timegm(&tm)) + sec;
}

// A rule in words, for the table a person reads (the JSON keeps plant::spc::to_string's names).
const char* rule_words(plant::spc::Rule r) {
  switch (r) {
    case plant::spc::Rule::beyond_3_sigma: return "one value beyond 3 sigma";
    case plant::spc::Rule::two_of_three: return "two of three beyond 2 sigma";
    case plant::spc::Rule::four_of_five: return "four of five beyond 1 sigma";
    case plant::spc::Rule::eight_one_side: return "eight in a row on one side";
    case plant::spc::Rule::moving_range: return "a moving range above its limit";
  }
  return "?";
}

// Every Western Electric signal of a figure, listed: rule, the units of its pattern, the value.
std::string signals_table(const plant::FigureSpc& f) {
  if (f.chart.signals.empty()) return "<p class=note>No signal of any rule.</p>";
  std::string t = "<table class=signals><tr><th>rule</th><th>what</th><th>serial</th><th>lot</th><th>bench</th><th>run</th><th>run end</th><th>value</th><th>pattern from</th></tr>";
  for (const auto& g : f.chart.signals) {
    const auto& v = f.values[g.index];
    const auto& first = f.values[g.first];
    const std::string rule = g.rule == plant::spc::Rule::moving_range ? "MR" : std::to_string(static_cast<int>(g.rule));
    t += "<tr><td>" + rule + "</td><td>" + rule_words(g.rule) + (g.side > 0 ? ", above" : g.side < 0 ? ", below" : "") +
         "</td><td>" + html_escape(v.serial) + "</td><td>" + html_escape(v.lot.value_or("-")) + "</td><td>" + html_escape(v.bench) +
         "</td><td>" + std::to_string(v.run_id) + "</td><td>" + html_escape(v.ended_at.value_or("-")) + "</td><td>" + std::to_string(v.value) +
         "</td><td>" + (g.first == g.index ? std::string("-") : html_escape(first.serial) + " (" + html_escape(first.ended_at.value_or("-")) + ")") +
         "</td></tr>";
  }
  return t + "</table>";
}

// The per-lot view's table: each lot's n, mean, limits and whether it is out.
std::string lots_table(const plant::FigureSpc& f) {
  std::string t = "<table class=lots><tr><th>#</th><th>lot</th><th>n</th><th>mean</th><th>LCL</th><th>UCL</th><th>z</th><th></th></tr>";
  for (std::size_t k = 0; k < f.lots.size(); ++k) {
    const auto& l = f.lots[k];
    t += "<tr><td>" + std::to_string(k + 1) + "</td><td>" + html_escape(l.lot) + "</td><td>" + std::to_string(l.n) + "</td><td>" +
         std::to_string(l.mean) + "</td><td>" + std::to_string(l.lcl) + "</td><td>" + std::to_string(l.ucl) + "</td><td>" +
         std::to_string(l.z) + "</td><td>" + (l.side != 0 ? "<b style=\"color:#d62728\">out of limits</b>" : "") + "</td></tr>";
  }
  return t + "</table>";
}

}  // namespace

std::string fleet_html(const std::vector<plant::FigureSpc>& figures, const nlohmann::json& charts,
                       const nlohmann::json& proportions) {
  using nlohmann::json;
  json data = json::array();
  std::string body = "<h1>Fleet control charts</h1><p class=note>Individuals and moving-range charts (limits: "
                     "centre &plusmn; 3 MRbar/1.128; MR limit 3.267 MRbar), the Western Electric rules, units beyond "
                     "the limits in red.</p>";
  body += proportion_html(proportions);
  for (std::size_t i = 0; i < figures.size(); ++i) {
    const auto& f = figures[i];
    const json& c = charts.at(i);
    json x = json::array(), mr = json::array();
    for (std::size_t k = 0; k < f.values.size(); ++k) {
      x.push_back(f.values[k].value);
      mr.push_back(std::isfinite(f.chart.mr[k]) ? json(f.chart.mr[k]) : json(nullptr));
    }
    json t = json::array();
    for (const auto& v : f.values) {
      const auto at = v.ended_at ? epoch_of(*v.ended_at) : std::nullopt;
      t.push_back(at ? json(*at) : json(nullptr));
    }
    json signals = json::array();
    for (const auto& g : f.chart.signals)
      signals.push_back({{"rule", static_cast<int>(g.rule)}, {"index", g.index}, {"first", g.first}});
    json lots = json::array();
    for (const auto& l : f.lots) lots.push_back({{"lot", l.lot}, {"mean", l.mean}, {"ucl", l.ucl}, {"lcl", l.lcl}, {"side", l.side}});
    const std::string unit = figure_unit(f.name);
    data.push_back({{"name", f.name}, {"unit", unit}, {"x", x}, {"t", t}, {"mr", mr}, {"center", f.chart.center},
                    {"ucl", f.chart.ucl}, {"lcl", f.chart.lcl}, {"mr_bar", f.chart.mr_bar}, {"mr_ucl", f.chart.mr_ucl},
                    {"signals", signals}, {"lots", lots}});
    body += "<h2>" + html_escape(f.name) + (unit.empty() ? std::string() : " (" + html_escape(unit) + ")") + "</h2><p class=note>" +
            std::to_string(f.values.size()) + " values; limits from " + html_escape(f.baseline) + "; " +
            std::to_string(c["signals"].size()) + " signals" + (f.values.size() >= 400 ? "; the values drawn as a line, the signals marked" : "") +
            "</p><div id=chart" + std::to_string(i) + "></div><div id=mr" + std::to_string(i) + "></div>";
    body += signals_table(f);
    if (!f.lots.empty()) body += "<div id=lots" + std::to_string(i) + "></div>" + lots_table(f);
    if (!f.flagged_units.empty()) {
      body += "<table><tr><th>serial</th><th>lot</th><th>bench</th><th>run</th><th>unit</th><th>value</th></tr>";
      for (auto k : f.flagged_units) {
        const auto& v = f.values[k];
        body += "<tr><td>" + html_escape(v.serial) + "</td><td>" + html_escape(v.lot.value_or("-")) + "</td><td>" +
                html_escape(v.bench) + "</td><td>" + std::to_string(v.run_id) + "</td><td>" +
                std::to_string(v.unit_index) + "</td><td>" + std::to_string(v.value) + "</td></tr>";
      }
      body += "</table>";
    }
    if (c.contains("flagged_lots") && !c["flagged_lots"].empty()) {
      body += "<p>Lots out of limits (lot mean against centre &plusmn; 3 sigma sqrt(1/n + 1/n<sub>baseline</sub>)):";
      for (const auto& l : c["lots"])
        if (l["side"].get<int>() != 0)
          body += " <b style=\"color:#d62728\">" + html_escape(l["lot"].get<std::string>()) + "</b> (mean " +
                  std::to_string(l["mean"].get<double>()) + ", n " + std::to_string(l["n"].get<std::size_t>()) +
                  ", z " + std::to_string(l["z"].get<double>()) + ")";
      body += "</p>";
    }
    if (c.contains("lot_comparison")) {
      const json& l = c["lot_comparison"];
      body += "<p>lot " + html_escape(l["lot_a"].get<std::string>()) + " &minus; lot " +
              html_escape(l["lot_b"].get<std::string>()) + ": " + std::to_string(l["difference"].get<double>()) + " [" +
              std::to_string(l["low"].get<double>()) + ", " + std::to_string(l["high"].get<double>()) + "] (Welch, " +
              std::to_string(static_cast<int>(std::lround(100 * l["level"].get<double>()))) + "%)</p>";
    }
  }
  return "<!doctype html><html><head><meta charset=utf-8><title>fogbench fleet</title><style>" +
         std::string(vendor::kUplotCss) + "</style><style>" + kStyle + "</style></head><body>" + body + "<script>" +
         std::string(vendor::kUplotJs) + "</script><script>const DATA=" + script_json(data) + ";" + kDraw +
         "</script></body></html>\n";
}

}  // namespace fogbench::cli
