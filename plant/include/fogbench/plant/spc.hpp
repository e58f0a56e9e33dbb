// The fleet statistics (issue 14): individuals and moving-range control charts, the Western
// Electric rules, distributions by group, and Welch's comparison of two lots. Pure: no I/O, no
// clock; the fleet queries (fleet.hpp) hand them numbers in time order.
#pragma once

#include <cstddef>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace fogbench::plant::spc {

// The four classic Western Electric rules on the individuals chart (sigma = MRbar / d2):
enum class Rule {
  beyond_3_sigma = 1,  // 1: one point beyond 3 sigma
  two_of_three = 2,    // 2: two of three consecutive points beyond 2 sigma, same side
  four_of_five = 3,    // 3: four of five consecutive points beyond 1 sigma, same side
  eight_one_side = 4,  // 4: eight consecutive points on one side of the centre line
  moving_range = 5,    // the moving-range chart: a range above its upper limit
};
std::string to_string(Rule r);

struct Signal {
  Rule rule = Rule::beyond_3_sigma;
  std::size_t index = 0;        // the point that completes the pattern
  std::size_t first = 0;        // the pattern's first point (== index for rules 1 and 5)
  int side = 0;                 // +1 above the centre, -1 below (0: moving range)
};

// d2 and D4 for moving ranges of two (the constants every SPC text tables).
inline constexpr double kD2 = 1.128;
inline constexpr double kD4 = 3.267;

struct ImrChart {
  std::size_t baseline_begin = 0, baseline_end = 0;  // [begin, end) of the values: the limits' window
  double center = 0;      // mean of the baseline's individuals
  double mr_bar = 0;      // mean moving range within the baseline
  double sigma = 0;       // mr_bar / d2
  double ucl = 0, lcl = 0;           // center +- 3 sigma
  double mr_ucl = 0;                 // D4 mr_bar (the MR chart's lower limit is 0)
  std::vector<double> mr;            // mr[i] = |x[i] - x[i-1]|; mr[0] is NaN
  std::vector<Signal> signals;       // every rule's signals, by index then rule
};

// The chart of `x` (in time order) with limits from x[baseline_begin, baseline_end), which
// must hold at least 2 values. Throws std::invalid_argument otherwise.
ImrChart imr_chart(std::span<const double> x, std::size_t baseline_begin, std::size_t baseline_end);

// The Western Electric rules 1-4 on x against centre and sigma.
std::vector<Signal> western_electric(std::span<const double> x, double center, double sigma);

struct Summary {
  std::size_t n = 0;
  double mean = 0, sd = 0, min = 0, median = 0, max = 0;  // sd: sample (n - 1); 0 when n < 2
};
Summary summarize(std::span<const double> x);

// Welch's comparison of two samples: the difference of means a - b with its two-sided interval
// at `level`, on the Welch-Satterthwaite degrees of freedom.
struct Comparison {
  Summary a, b;
  double diff = 0, se = 0, dof = 0, t_crit = 0, low = 0, high = 0, level = 0.95;
  double t = 0, p_value = 1;  // the test of no difference, two-sided
};
// Needs two values in each; throws std::invalid_argument otherwise.
Comparison welch(std::span<const double> a, std::span<const double> b, double level = 0.95);

// Student's t: the distribution function and the quantile (dof > 0).
double student_t_cdf(double t, double dof);
double student_t_quantile(double p, double dof);

}  // namespace fogbench::plant::spc
