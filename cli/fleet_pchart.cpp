// fogctl fleet spc: proportion charts of verdicts (fleet_pchart.hpp).
#include "fleet_pchart.hpp"

#include <cstdio>
#include <map>
#include <set>

#include "html.hpp"
#include "table.hpp"

namespace fogbench::cli {

using nlohmann::json;

namespace {
std::string pchart_pct(double p) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.2f%%", 100 * p);
  return buf;
}
}  // namespace

json proportion_json(const plant::ProportionChart& ch) {
  json groups = json::array();
  for (const auto& g : ch.groups)
    groups.push_back({{"bench", g.bench}, {"period", g.period}, {"n", g.n}, {"count", g.count}, {"p", g.p},
                      {"lcl", g.lcl}, {"ucl", g.ucl}, {"side", g.side}});
  return {{"verdict", ch.verdict}, {"period", ch.period}, {"baseline", ch.baseline}, {"baseline_n", ch.baseline_n},
          {"baseline_count", ch.baseline_count}, {"p_bar", ch.p_bar}, {"groups", groups},
          {"flagged_benches", ch.flagged_benches}};
}

std::string proportion_text(const plant::ProportionChart& ch) {
  std::string s = ch.verdict + " verdicts per bench per " + ch.period + " (p-chart): p-bar " + pchart_pct(ch.p_bar) + " (" +
                  std::to_string(ch.baseline_count) + " of " + std::to_string(ch.baseline_n) + ", limits from " +
                  ch.baseline + "); limits p-bar +- 3 sqrt(p-bar (1 - p-bar) / n)\n";
  Table t({ch.period, "bench", "verdicts", ch.verdict, "p", "LCL", "UCL", "out"});
  for (const auto& g : ch.groups)
    t.add({g.period, g.bench, std::to_string(g.n), std::to_string(g.count), pchart_pct(g.p), pchart_pct(g.lcl), pchart_pct(g.ucl),
           g.side > 0 ? "ABOVE" : g.side < 0 ? "below" : ""});
  s += t.str();
  s += "  benches out of limits: ";
  if (ch.flagged_benches.empty()) s += "none";
  for (std::size_t i = 0; i < ch.flagged_benches.size(); ++i) s += (i ? ", " : "") + ch.flagged_benches[i];
  return s + "\n";
}

std::string proportion_html(const json& proportions) {
  std::string body;
  for (const auto& ch : proportions) {
    const std::string verdict = ch["verdict"].get<std::string>();
    std::set<std::string> periods;
    std::map<std::string, std::map<std::string, const json*>> cells;  // bench -> period -> group
    for (const auto& g : ch["groups"]) {
      periods.insert(g["period"].get<std::string>());
      cells[g["bench"].get<std::string>()][g["period"].get<std::string>()] = &g;
    }
    body += "<h2>" + html_escape(verdict) + " verdicts per bench per " + html_escape(ch["period"].get<std::string>()) +
            " (p-chart)</h2><p class=note>p-bar " + pchart_pct(ch["p_bar"].get<double>()) + " (" +
            std::to_string(ch["baseline_count"].get<std::int64_t>()) + " of " +
            std::to_string(ch["baseline_n"].get<std::int64_t>()) + ", limits from " +
            html_escape(ch["baseline"].get<std::string>()) +
            "); 3-sigma binomial limits per cell (shown on hover); out of limits in red. Benches out of limits: ";
    const auto& fl = ch["flagged_benches"];
    if (fl.empty()) body += "none";
    for (std::size_t i = 0; i < fl.size(); ++i) body += (i ? ", " : "") + html_escape(fl[i].get<std::string>());
    body += "</p><table class=pchart><tr><th>bench</th>";
    for (const auto& p : periods) body += "<th>" + html_escape(p) + "</th>";
    body += "</tr>";
    for (const auto& [bench, row] : cells) {
      body += "<tr><td>" + html_escape(bench) + "</td>";
      for (const auto& p : periods) {
        auto it = row.find(p);
        if (it == row.end()) {
          body += "<td></td>";
          continue;
        }
        const json& g = *it->second;
        const int side = g["side"].get<int>();
        body += std::string("<td") + (side != 0 ? " class=out" : "") + " title=\"" +
                std::to_string(g["count"].get<std::int64_t>()) + " of " + std::to_string(g["n"].get<std::int64_t>()) +
                "; limits " + pchart_pct(g["lcl"].get<double>()) + " .. " + pchart_pct(g["ucl"].get<double>()) + "\">" +
                pchart_pct(g["p"].get<double>()) + "</td>";
      }
      body += "</tr>";
    }
    body += "</table>";
  }
  return body;
}

}  // namespace fogbench::cli
