// Proportion charts (p-charts) of verdicts across the fleet (issue 14: "which bench produces more
// marginal verdicts?"): the fraction of a verdict (marginal, fail) per bench per period, with
// p-bar and 3-sigma binomial limits from a stated baseline window, the benches out of limits
// flagged. verdict_values reads the plant; the rest is pure (no I/O).
#pragma once

#include <cstdint>
#include <expected>
#include <optional>
#include <string>
#include <vector>

#include "fogbench/plant/fleet.hpp"
#include "fogbench/plant/fleet_spc.hpp"

namespace fogbench::plant {

// One unit's verdict in one run: its latest verification of that run.
struct VerdictValue {
  std::string bench;
  std::int64_t run_id = 0;
  int unit_index = 0;
  std::string serial;
  std::optional<std::string> lot, ended_at;
  std::string verdict;  // pass | marginal | fail
};
// In the order the runs ended (then bench, run, unit).
PlantResult<std::vector<VerdictValue>> verdict_values(Connection& c, const FleetFilter& f);

namespace spc {
// The binomial 3-sigma limits of a proportion of a subgroup of n: p_bar +- 3 sqrt(p_bar (1 -
// p_bar) / n), clipped to [0, 1].
struct PLimits {
  double lcl = 0, ucl = 0;
};
PLimits p_limits(double p_bar, std::int64_t n);
}  // namespace spc

// One subgroup: one bench's verdicts in one period.
struct ProportionGroup {
  std::string bench, period;
  std::int64_t n = 0, count = 0;  // verdicts, and those of the chart's verdict
  double p = 0, lcl = 0, ucl = 0;
  int side = 0;                   // +1 above the UCL, -1 below the LCL, 0 within
};

struct ProportionChart {
  std::string verdict;            // marginal | fail
  std::string period;             // month | week | day
  std::string baseline;           // the window in words
  std::int64_t baseline_n = 0, baseline_count = 0;
  double p_bar = 0;               // baseline_count / baseline_n
  std::vector<ProportionGroup> groups;  // by period, then bench
  std::vector<std::string> flagged_benches;  // with a group out of limits, in name order
};

// The period of a run's end (ISO 8601 UTC text): "2026-03" (month), "2026-03-04" (day), or
// "2026-03-02/w" (week: the Monday that starts it). "(no end)" for a run without an end.
std::string period_of(const std::string& ended_at, const std::string& period);

// The chart of `verdict` over these verdicts per bench per period. The baseline: the runs that
// ended in [b.from, b.to) when either is given, else the first b.first_n verdicts (all when
// fewer; default 2000). Errors (named): an unknown period or verdict, a baseline window holding
// no verdicts. A p-bar of 0 or 1 gives limits of zero width: computed, as the rule says.
std::expected<ProportionChart, std::string> proportion_chart(const std::vector<VerdictValue>& values,
                                                             const std::string& verdict, const Baseline& b,
                                                             const std::string& period = "month");

}  // namespace fogbench::plant
