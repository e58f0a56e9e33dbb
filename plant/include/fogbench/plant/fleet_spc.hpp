// One figure's control chart over the fleet (issue 14, `fogctl fleet spc`): the values in time
// order (fleet.hpp's figure_values), the limits from a stated baseline window, the Western
// Electric signals, the units flagged, and the comparison of two lots. Pure: no I/O.
#pragma once

#include <expected>
#include <optional>
#include <string>
#include <vector>

#include "fogbench/plant/fleet.hpp"
#include "fogbench/plant/spc.hpp"

namespace fogbench::plant {

// The window the limits come from: the first `first_n` values, or the runs that ended in
// [from, to) (ISO 8601 text, compared as text: same format as the plant's). Neither: the first
// 100 values (all when fewer).
struct Baseline {
  std::optional<std::size_t> first_n;
  std::optional<std::string> from, to;
};

// One lot's mean against the chart's centre: limits centre +- 3 sigma sqrt(1/n + 1/n_baseline)
// (the difference of two means, the lot's and the baseline's, with the chart's sigma), so a lot
// whose units all shifted a little stands out even when none of its units is beyond the limits.
struct LotMean {
  std::string lot;
  std::size_t n = 0;
  double mean = 0, lcl = 0, ucl = 0, z = 0;  // z: (mean - centre) / (sigma sqrt(1/n + 1/n_baseline))
  int side = 0;                              // +1 above, -1 below, 0 within
};

struct FigureSpc {
  std::string name;
  std::vector<FigureValue> values;   // in time order
  spc::ImrChart chart;
  std::string baseline;              // the window in words: "values 1..100 (runs ended ... to ...)"
  // Units whose value is beyond the individuals' limits (rule 1): outliers against the fleet.
  std::vector<std::size_t> flagged_units;  // indices into values
  std::vector<LotMean> lots;               // every lot's mean (values without a lot: none), by name
  std::vector<std::string> flagged_lots;   // lots whose mean is beyond its limits
};

// Needs two values in the window; the error says which window and how many it held.
std::expected<FigureSpc, std::string> figure_spc(const std::string& name, std::vector<FigureValue> values,
                                                 const Baseline& baseline);

// Welch's comparison of lot a and lot b on these values (error: fewer than two in one of them).
std::expected<spc::Comparison, std::string> compare_lots(const std::vector<FigureValue>& values, const std::string& a,
                                                         const std::string& b, double level = 0.95);

// Summaries by group: "lot", "bench" or "month" (of the run's end, YYYY-MM). Groups in name order
// (values without a lot under "(none)").
std::expected<std::vector<std::pair<std::string, spc::Summary>>, std::string> distribution(
    const std::vector<FigureValue>& values, const std::string& by);

}  // namespace fogbench::plant
