// One figure's control chart over the fleet (fleet_spc.hpp). Pure.
#include "fogbench/plant/fleet_spc.hpp"

#include <cmath>
#include <map>

namespace fogbench::plant {

std::expected<FigureSpc, std::string> figure_spc(const std::string& name, std::vector<FigureValue> values,
                                                 const Baseline& b) {
  std::size_t begin = 0, end = 0;
  std::string words;
  if (b.from || b.to) {
    bool in = false;
    begin = values.size();
    for (std::size_t i = 0; i < values.size(); ++i) {
      const std::string at = values[i].ended_at.value_or("");
      const bool inside = (!b.from || at >= *b.from) && (!b.to || at < *b.to);
      if (inside && !in) begin = i, in = true;
      if (inside) end = i + 1;
    }
    words = "runs ended in [" + b.from.value_or("the first") + ", " + b.to.value_or("the last") + ")";
  } else {
    end = std::min(values.size(), b.first_n.value_or(100));
    words = "the first " + std::to_string(end) + " values";
  }
  if (end <= begin || end - begin < 2)
    return std::unexpected("figure '" + name + "': the baseline (" + words + ") holds " +
                           std::to_string(end > begin ? end - begin : 0) + " values; at least 2 are needed");
  FigureSpc f;
  f.name = name;
  f.baseline = words + ": values " + std::to_string(begin + 1) + ".." + std::to_string(end) + " of " +
               std::to_string(values.size());
  std::vector<double> x;
  x.reserve(values.size());
  for (const auto& v : values) x.push_back(v.value);
  f.chart = spc::imr_chart(x, begin, end);
  for (const auto& s : f.chart.signals)
    if (s.rule == spc::Rule::beyond_3_sigma) f.flagged_units.push_back(s.index);
  // Each lot's mean against the centre.
  std::map<std::string, std::pair<std::size_t, double>> by_lot;
  for (const auto& v : values)
    if (v.lot) {
      auto& [n, sum] = by_lot[*v.lot];
      ++n;
      sum += v.value;
    }
  const double n_base = static_cast<double>(end - begin);
  for (const auto& [lot, ns] : by_lot) {
    LotMean m;
    m.lot = lot;
    m.n = ns.first;
    m.mean = ns.second / static_cast<double>(ns.first);
    const double se = f.chart.sigma * std::sqrt(1.0 / static_cast<double>(m.n) + 1.0 / n_base);
    m.lcl = f.chart.center - 3 * se;
    m.ucl = f.chart.center + 3 * se;
    m.z = se > 0 ? (m.mean - f.chart.center) / se : 0.0;
    m.side = m.mean > m.ucl ? 1 : m.mean < m.lcl ? -1 : 0;
    if (m.side != 0) f.flagged_lots.push_back(lot);
    f.lots.push_back(std::move(m));
  }
  f.values = std::move(values);
  return f;
}

std::expected<spc::Comparison, std::string> compare_lots(const std::vector<FigureValue>& values, const std::string& a,
                                                         const std::string& b, double level) {
  std::vector<double> xa, xb;
  for (const auto& v : values) {
    if (v.lot == a) xa.push_back(v.value);
    if (v.lot == b) xb.push_back(v.value);
  }
  if (xa.size() < 2 || xb.size() < 2)
    return std::unexpected("comparing lots '" + a + "' (" + std::to_string(xa.size()) + " values) and '" + b + "' (" +
                           std::to_string(xb.size()) + " values): at least 2 are needed in each");
  return spc::welch(xa, xb, level);
}

std::expected<std::vector<std::pair<std::string, spc::Summary>>, std::string> distribution(
    const std::vector<FigureValue>& values, const std::string& by) {
  if (by != "lot" && by != "bench" && by != "month")
    return std::unexpected("--by: expected lot, bench or month, not '" + by + "'");
  std::map<std::string, std::vector<double>> groups;
  for (const auto& v : values) {
    std::string key = by == "lot" ? v.lot.value_or("(none)") : by == "bench" ? v.bench
                                                                              : v.ended_at.value_or("(none)").substr(0, 7);
    groups[key].push_back(v.value);
  }
  std::vector<std::pair<std::string, spc::Summary>> out;
  for (const auto& [k, xs] : groups) out.emplace_back(k, spc::summarize(xs));
  return out;
}

}  // namespace fogbench::plant
