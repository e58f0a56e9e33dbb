// fogctl fleet spc --html (fleet_html.hpp).
#include "fleet_html.hpp"
#include "fleet_pchart.hpp"
#include "html.hpp"

#include <cmath>

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

constexpr const char* kDraw = R"js(
for (const [i, c] of DATA.entries()) {
  const host = document.getElementById('chart' + i), mrHost = document.getElementById('mr' + i);
  const n = c.x.length, idx = Array.from({length: n}, (_, k) => k + 1);
  const flat = v => idx.map(() => v);
  const flagged = c.x.map((v, k) => c.flag[k] ? v : null);
  const w = Math.min(1100, window.innerWidth - 40);
  new uPlot({title: c.name + ': individuals', width: w, height: 280, scales: {x: {time: false}},
    series: [{label: 'unit'}, {label: c.name, stroke: '#1f77b4', width: 1, points: {show: n < 400}},
             {label: 'centre', stroke: '#2ca02c', dash: [6, 4]}, {label: 'UCL', stroke: '#d62728'},
             {label: 'LCL', stroke: '#d62728'},
             {label: 'flagged', stroke: 'transparent', points: {show: true, size: 8, fill: '#d62728', stroke: '#d62728'}}]},
    [idx, c.x, flat(c.center), flat(c.ucl), flat(c.lcl), flagged], host);
  new uPlot({title: c.name + ': moving range', width: w, height: 200, scales: {x: {time: false}},
    series: [{label: 'unit'}, {label: 'MR', stroke: '#7f7f7f', width: 1}, {label: 'MRbar', stroke: '#2ca02c', dash: [6, 4]},
             {label: 'UCL', stroke: '#d62728'}]},
    [idx, c.mr, flat(c.mr_bar), flat(c.mr_ucl)], mrHost);
}
)js";

constexpr const char* kStyle =
    "body{font-family:system-ui,sans-serif;margin:20px;color:#222}h1{font-size:22px}h2{font-size:17px;margin-top:28px}"
    "table{border-collapse:collapse;font-size:13px}td,th{border:1px solid #ccc;padding:2px 6px;text-align:left}"
    ".note{color:#555;font-size:13px}.pchart td.out{color:#d62728;font-weight:bold;background:#fde8e8}";

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
    json x = json::array(), mr = json::array(), flag = json::array();
    std::vector<bool> flagged(f.values.size(), false);
    for (auto k : f.flagged_units) flagged[k] = true;
    for (std::size_t k = 0; k < f.values.size(); ++k) {
      x.push_back(f.values[k].value);
      mr.push_back(std::isfinite(f.chart.mr[k]) ? json(f.chart.mr[k]) : json(nullptr));
      flag.push_back(flagged[k] ? 1 : 0);
    }
    data.push_back({{"name", f.name}, {"x", x}, {"mr", mr}, {"flag", flag}, {"center", f.chart.center},
                    {"ucl", f.chart.ucl}, {"lcl", f.chart.lcl}, {"mr_bar", f.chart.mr_bar}, {"mr_ucl", f.chart.mr_ucl}});
    body += "<h2>" + html_escape(f.name) + "</h2><p class=note>" + std::to_string(f.values.size()) +
            " values; limits from " + html_escape(f.baseline) + "; " + std::to_string(c["signals"].size()) +
            " signals</p><div id=chart" + std::to_string(i) + "></div><div id=mr" + std::to_string(i) + "></div>";
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
