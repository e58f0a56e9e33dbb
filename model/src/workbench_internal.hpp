// What diagnose's files share inside model/: one step of the search (diagnose_once, in
// workbench_diagnose.cpp), the language's generated candidates (workbench_search.cpp) and
// the small helpers both use (one copy each).
#pragma once

#include <cmath>
#include <cstdio>
#include <expected>
#include <limits>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "fogbench/model/workbench.hpp"

namespace fogbench::model::workbench {

// "Not measured" in a figure (deg/h or a ratio): printed as "-", null in JSON.
inline constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// Why a term cannot be evaluated on a run (Ta or ton not recorded), empty when it can.
std::string missing_signal_of(const Expr& e, const RunData& run);

// The candidates' one order: the detected first, then the evaluated, each group by delta BIC;
// the skipped last, as they were (a stable sort).
void sort_detected_first(std::vector<Candidate>& candidates);

namespace wbi {

// The runs side by side (first, then rest), as unit_noise_floor and time_drift read them: the
// runs as given when rest already follows first in one array (fogctl hands diagnose one vector,
// the fit run first), else copies into `copy` (each run as long as it is: on a 3-day run 14 MB).
inline std::span<const RunData> side_by_side(const RunData& first, std::span<const RunData> rest, std::vector<RunData>& copy) {
  if (rest.empty()) return {&first, 1};
  if (rest.data() == &first + 1) return {&first, rest.size() + 1};
  copy.reserve(rest.size() + 1);
  copy.push_back(first);
  copy.insert(copy.end(), rest.begin(), rest.end());
  return copy;
}

// v with `digits` decimals, for the workbench's sentences.
inline std::string fmt(double v, int digits) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", digits, v);
  return buf;
}

// The weighted correlation of a and b (0 when either is constant or no weight is left).
inline double weighted_corr(std::span<const double> a, std::span<const double> b, std::span<const double> w) {
  double sw = 0, ma = 0, mb = 0;
  for (std::size_t t = 0; t < a.size(); ++t) {
    sw += w[t];
    ma += w[t] * a[t];
    mb += w[t] * b[t];
  }
  if (!(sw > 0)) return 0.0;
  ma /= sw;
  mb /= sw;
  double sab = 0, saa = 0, sbb = 0;
  for (std::size_t t = 0; t < a.size(); ++t) {
    sab += w[t] * (a[t] - ma) * (b[t] - mb);
    saa += w[t] * (a[t] - ma) * (a[t] - ma);
    sbb += w[t] * (b[t] - mb) * (b[t] - mb);
  }
  return saa > 0 && sbb > 0 ? sab / std::sqrt(saa * sbb) : 0.0;
}

// find_jumps' thermal mask: marked[k] set where rt (a rate, degC/min) spans more than spread
// over the window [k - half, k + half] cut at the run's ends (marked[k] already set stays set);
// rt.size() == marked.size(). O(n) (workbench_nonthermal.cpp).
void mark_rate_changes(const std::vector<double>& rt, std::size_t half, double spread, std::vector<bool>& marked);

// A column's weighted sum of weights, mean and centred sum of squares, as weighted_corr
// computes them (the same additions in the same order), for weighted_corr_pair.
struct CorrStats {
  double sw = 0, m = 0, ss = 0;
};
inline CorrStats corr_stats(std::span<const double> a, std::span<const double> w) {
  CorrStats c;
  for (std::size_t t = 0; t < a.size(); ++t) {
    c.sw += w[t];
    c.m += w[t] * a[t];
  }
  if (!(c.sw > 0)) return c;
  c.m /= c.sw;
  for (std::size_t t = 0; t < a.size(); ++t) c.ss += w[t] * (a[t] - c.m) * (a[t] - c.m);
  return c;
}

// weighted_corr(a, b, w) and weighted_corr(b, a, w), bit for bit (the products rounded in each
// order), in one pass over the columns: sa and sb are corr_stats of a and b with the same w.
inline std::pair<double, double> weighted_corr_pair(std::span<const double> a, const CorrStats& sa, std::span<const double> b,
                                                    const CorrStats& sb, std::span<const double> w) {
  if (!(sa.sw > 0)) return {0.0, 0.0};
  double sab = 0, sba = 0;
  for (std::size_t t = 0; t < a.size(); ++t) {
    const double da = a[t] - sa.m, db = b[t] - sb.m;
    sab += w[t] * da * db;
    sba += w[t] * db * da;
  }
  if (!(sa.ss > 0 && sb.ss > 0)) return {0.0, 0.0};
  return {sab / std::sqrt(sa.ss * sb.ss), sba / std::sqrt(sb.ss * sa.ss)};
}

// The residual of a model on a run, with the weights of compare (flagged, non-finite and
// settle samples 0; spikes about the 61 s average 0), the residual 0 where the weight is.
struct Residual {
  std::vector<double> r, w;
};
std::expected<Residual, FitError> residual_of(const Model& m, const RunData& run);

// Bias jumps in a model's residual on a run (workbench_nonthermal.cpp): steps of t >= o.jump_t
// found by a change-point scan, at most o.max_jumps; `removed` (when given, sized as the run)
// gets each jump's size (deg/h) added from its time on.
std::vector<BiasJump> find_jumps(const Model& m, const RunData& run, const DiagnoseOptions& o, std::vector<double>* removed);

// The term of a drift in time (trun, h since the run's start) as diagnose names it.
inline constexpr const char* kTimeDriftName = "a drift in time (ageing/outgassing), not thermal";
inline constexpr const char* kTimeDriftExplanation =
    "the residual follows the run's own clock, not temperature: the light source ageing, outgassing in the coil's potting or "
    "the housing, a slow electronics drift";

// A candidate of the language search: the term (canonical, no lag) and what it would mean.
struct Generated {
  std::string expr, effect, explanation;
};

// The candidates diagnose's language search generates, canonical expression and name (empty
// when the options ask for too many): tests/model/term_ops_test.cpp checks them against
// kTermOps' `searched`.
std::vector<Generated> search_expressions(const DiagnoseOptions& o, bool has_ta, bool has_ton);

struct SearchStats {
  std::size_t scanned = 0;   // generated candidates lag-scanned
  std::size_t refitted = 0;  // candidates refitted and scored (library and generated)
  std::size_t pruned = 0;    // candidates not refitted: their one-column update falls short (prune_fraction)
};

// What diagnose computed already for a step's own inputs: the base (m refitted on the fit run
// as diagnose_once refits it) and the unit's noise floor read under it over the same runs. Given
// when the step's runs are the ones these were computed on (no bias jump removed), so that
// diagnose_once uses them instead of computing the same numbers again.
struct StepHint {
  const Model* base = nullptr;
  const NoiseFloor* floor = nullptr;
};

// One step: the model's terms refitted on the fit run, every library candidate (and the
// generated ones, screened by their lag scan's gain to o.refit_top) refitted and scored.
std::expected<Diagnosis, FitError> diagnose_once(const Model& m, const RunData& fit_run, std::span<const RunData> held_out,
                                                 const DiagnoseOptions& o, const std::vector<Generated>& gen, SearchStats* stats,
                                                 const StepHint& hint = {});

}  // namespace wbi
}  // namespace fogbench::model::workbench
