// Proportion charts of verdicts (verdicts.hpp).
#include "fogbench/plant/verdicts.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <set>

#include "fleet_query.hpp"

namespace fogbench::plant {

PlantResult<std::vector<VerdictValue>> verdict_values(Connection& c, const FleetFilter& f) {
  // The verdict each run decided for each unit (the bench's one verdict, issue 24: a plan's or
  // the analysis settings'), with the unit and run filters of fleet.cpp.
  const std::string sql =
      "SELECT r.bench_id, r.run_id, u.unit_index, u.serial, u.lot, "
      "to_char(r.ended_at AT TIME ZONE 'UTC', 'YYYY-MM-DD\"T\"HH24:MI:SS\"Z\"'), v.verdict "
      "FROM (SELECT DISTINCT ON (bench_id, run_id, unit_index) bench_id, run_id, unit_index, verdict "
      "      FROM fogbench.verdicts ORDER BY bench_id, run_id, unit_index, verdict_id DESC) v "
      "JOIN fogbench.units u USING (bench_id, run_id, unit_index) JOIN fogbench.runs r USING (bench_id, run_id) "
      "WHERE ($1::text IS NULL OR u.lot = $1) AND ($2::text IS NULL OR r.bench_id = $2) "
      "AND ($3::text IS NULL OR u.serial = $3) AND ($4::timestamptz IS NULL OR r.ended_at >= $4::timestamptz) "
      "AND ($5::timestamptz IS NULL OR r.ended_at < $5::timestamptz) "
      "ORDER BY r.ended_at NULLS LAST, r.bench_id, r.run_id, u.unit_index";
  auto rows = detail::query_scan(c, sql, {f.lot, f.bench, f.serial, f.since, f.until}, "read the verdicts");
  if (!rows) return std::unexpected(rows.error());
  std::vector<VerdictValue> out;
  out.reserve(rows->rows.size());
  for (auto& r : rows->rows)
    out.push_back({r[0].value_or(""), r[1] ? std::stoll(*r[1]) : 0, r[2] ? std::stoi(*r[2]) : 0, r[3].value_or(""),
                   r[4], r[5], r[6].value_or("")});
  return out;
}

namespace spc {
PLimits p_limits(double p_bar, std::int64_t n) {
  if (n <= 0) return {0, 1};
  const double s = std::sqrt(p_bar * (1 - p_bar) / static_cast<double>(n));
  return {std::max(0.0, p_bar - 3 * s), std::min(1.0, p_bar + 3 * s)};
}
}  // namespace spc

std::string period_of(const std::string& ended_at, const std::string& period) {
  if (ended_at.size() < 10) return "(no end)";
  if (period == "month") return ended_at.substr(0, 7);
  if (period == "day") return ended_at.substr(0, 10);
  // week: the Monday on or before the day.
  int y = 0;
  unsigned m = 0, d = 0;
  if (std::sscanf(ended_at.c_str(), "%d-%u-%u", &y, &m, &d) != 3) return "(no end)";
  using namespace std::chrono;
  const sys_days day{year{y} / month{m} / std::chrono::day{d}};
  const sys_days monday = day - (weekday{day} - Monday);
  const year_month_day ymd{monday};
  char buf[32];
  std::snprintf(buf, sizeof buf, "%04d-%02u-%02u/w", static_cast<int>(ymd.year()), static_cast<unsigned>(ymd.month()),
                static_cast<unsigned>(ymd.day()));
  return buf;
}

std::expected<ProportionChart, std::string> proportion_chart(const std::vector<VerdictValue>& values,
                                                             const std::string& verdict, const Baseline& b,
                                                             const std::string& period) {
  if (verdict != "marginal" && verdict != "fail" && verdict != "pass")
    return std::unexpected("p-chart: the verdict must be pass, marginal or fail, not '" + verdict + "'");
  if (period != "month" && period != "week" && period != "day")
    return std::unexpected("--period: expected month, week or day, not '" + period + "'");
  ProportionChart ch;
  ch.verdict = verdict;
  ch.period = period;
  std::size_t first = 0, last = 0;  // the window when a count
  if (b.from || b.to) {
    for (const auto& v : values) {
      const std::string at = v.ended_at.value_or("");
      if (at.empty() || (b.from && at < *b.from) || (b.to && at >= *b.to)) continue;
      ++ch.baseline_n;
      ch.baseline_count += v.verdict == verdict;
    }
    ch.baseline = "verdicts of runs ended in [" + b.from.value_or("the first") + ", " + b.to.value_or("the last") + ")";
  } else {
    last = std::min(values.size(), b.first_n.value_or(2000));
    for (std::size_t i = first; i < last; ++i) ch.baseline_count += values[i].verdict == verdict;
    ch.baseline_n = static_cast<std::int64_t>(last);
    ch.baseline = "the first " + std::to_string(last) + " verdicts";
    if (last > 0)
      ch.baseline += " (runs ended " + values.front().ended_at.value_or("-") + " to " +
                     values[last - 1].ended_at.value_or("-") + ")";
  }
  if (ch.baseline_n == 0) return std::unexpected("p-chart of " + verdict + " verdicts: the baseline (" + ch.baseline +
                                                 ") holds no verdicts");
  ch.p_bar = static_cast<double>(ch.baseline_count) / static_cast<double>(ch.baseline_n);
  std::map<std::pair<std::string, std::string>, std::pair<std::int64_t, std::int64_t>> groups;  // (period, bench)
  for (const auto& v : values) {
    auto& g = groups[{period_of(v.ended_at.value_or(""), period), v.bench}];
    ++g.first;
    g.second += v.verdict == verdict;
  }
  std::set<std::string> flagged;
  for (const auto& [key, nd] : groups) {
    ProportionGroup g;
    g.period = key.first;
    g.bench = key.second;
    g.n = nd.first;
    g.count = nd.second;
    g.p = static_cast<double>(g.count) / static_cast<double>(g.n);
    const auto l = spc::p_limits(ch.p_bar, g.n);
    g.lcl = l.lcl;
    g.ucl = l.ucl;
    g.side = g.p > g.ucl ? 1 : g.p < g.lcl ? -1 : 0;
    if (g.side != 0) flagged.insert(g.bench);
    ch.groups.push_back(std::move(g));
  }
  ch.flagged_benches.assign(flagged.begin(), flagged.end());
  return ch;
}

}  // namespace fogbench::plant
