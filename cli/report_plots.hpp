// The report's plots: pure helpers on series (robust y-limits, key numbers for the printed
// legend, a temperature loop split by direction) and the plot specification that the page's
// script draws with uPlot. No I/O: tests/cli/report_plots_test.cpp checks them alone.
#pragma once

#include <cstddef>
#include <nlohmann/json.hpp>
#include <span>
#include <string>
#include <vector>

namespace fogbench::cli::plots {

// A plot's y-range that one outlier cannot set. Over the finite values of all the series:
// q_lo, q_hi the `tail` and 1 - tail quantiles (nearest rank, inward, so a single extreme value
// is never one of them when N >= 3), w = q_hi - q_lo; values beyond [q_lo - fence w,
// q_hi + fence w] are outliers; the range spans the other values and every value of `always`
// (limit lines, confidence bands), widened by `margin` of its span each side. With tail 0.01
// and fence 0.5 a Gaussian series' fence is +-4.65 sigma: 3 in a million samples beyond it.
// below / above: values of the series outside the returned range (drawn as markers at the edge).
struct YLimits {
  double lo = -1.0, hi = 1.0;
  std::size_t below = 0, above = 0;
  std::size_t outside() const { return below + above; }
};
YLimits robust_limits(const std::vector<std::span<const double>>& series, std::span<const double> always = {}, double tail = 0.01,
                      double fence = 0.5, double margin = 0.05);

// Key numbers of a series for its static (printed) legend, over the finite values.
struct Keys {
  std::size_t n = 0;
  double mean = 0.0, std = 0.0, min = 0.0, max = 0.0, last = 0.0;  // std with divisor n - 1
};
Keys keys(std::span<const double> y);
// "mean 0.002, std 0.147, min -0.52, max 0.61, last 0.013 deg/h" (3 significant digits).
std::string keys_text(const Keys& k, const std::string& unit);

// A run's output against T1 in time order, split by the direction of T1: heating where T1 rose
// by more than min_rise_c over the centred window of +-half_window samples, cooling where it
// fell by as much, holding otherwise. Each part keeps the time order, with NaN where the run is
// in another part (so a line breaks there instead of joining distant points). On a cycle
// heated and cooled through the same temperatures, an output that depends on the direction
// (hysteresis) draws the heating and cooling branches apart: a loop.
struct Loop {
  std::vector<double> heat_x, heat_y, cool_x, cool_y, hold_x, hold_y;  // x: T1, degC; y: output units
};
Loop split_by_direction(std::span<const double> t1_c, std::span<const double> y, int half_window = 30, double min_rise_c = 0.05);

// One plot of the report. kind: "time" (x = time, s), "lag" (x = lag, s), "step" (x = lineage
// step), "xy" (each series its own x, uPlot's mode 2).
struct Series {
  std::string name;
  std::vector<double> y, x;  // x only for "xy"
  std::string stroke;
  double width = 1.2;
  std::vector<int> dash;
  bool points = false, line = true;
  bool robust = true;        // counts toward the robust y-range (a limit line does not)
  std::string keys;          // the printed legend's text for it ("" = none, e.g. a limit line)
};
struct Plot {
  std::string id, kind = "time", title, xlabel, ylabel;
  std::vector<double> x;                 // time_s, lag_s or step, except for "xy"
  std::vector<Series> series;
  std::vector<double> always;            // y values the range must hold
  bool robust = true;                    // robust y-limits with outliers marked; else uPlot's own
  bool y_from_zero = false;
  bool log = false;                      // both axes logarithmic (an Allan deviation: "xy", not robust)
  std::vector<std::string> x_names;      // "step": what each step is, for the legend and the print
  nlohmann::json failures = nlohmann::json::array();  // "time": intervals shaded
};
// Appends the plot's specification (decimated to at most max_points per series, 4 significant
// digits) to `specs` and returns its HTML: the element uPlot draws into and the static legend
// that a printed page shows. The title states how many samples lie beyond the y-range.
std::string render(const Plot& p, nlohmann::json& specs, std::size_t max_points);

// The page's script: draws every spec of DATA.plots, sets data-plots on <body> to the count.
extern const char* const kPlotScript;
// The plots' style, the printed legend's included (@media print).
extern const char* const kPlotStyle;

}  // namespace fogbench::cli::plots
