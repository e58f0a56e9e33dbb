// Data quality before physics: sensor problems of a recorded run (a thermistor stuck, dropped
// out, out of its physical range, noisy, offset against its twin during holds or lagging the
// others; gyro spikes and saturation; time not in seconds) found and named by sensor and
// interval before a model is fitted, so that a sensor problem is never answered with a physical
// term. And the identification check of a fitted model: coefficients the run cannot determine.
// Pure: no I/O; fogctl decides what to print and whether to refuse (docs/data-quality.md).
#pragma once

#include <cstddef>
#include <cstdint>
#include <expected>
#include <string>
#include <string_view>
#include <vector>

#include "fogbench/model/run.hpp"

namespace fogbench::model {

struct Model;

enum class QualityKind : std::uint8_t {
  time_unit,     // time_s advances by about 1000 per sample: milliseconds, not seconds
  time_step,     // time_s not 1 s apart (and not milliseconds): the fits need 1 s samples
  dropout,       // readings not taken (NaN) and not flagged missing
  stuck,         // a reading that repeats exactly while the other temperatures move
  out_of_range,  // a thermistor outside the physical range of a coil (e.g. -273.15 degC: open)
  noisy,         // a thermistor's white noise far above a thermistor's
  offset,        // T1 and T2 disagree during settled holds, where the coil is uniform
  lag,           // a thermistor lags (or leads) its neighbours beyond what the coil allows
  spike,         // gyro samples far beyond its noise, a few seconds wide
  saturation,    // the gyro output pinned at its extreme value
};
std::string_view to_string(QualityKind k);

// One sensor problem, by sensor and interval.
struct QualityFlag {
  std::string sensor;          // "T1", "T2", "Ta", "gyro" or "time_s"
  QualityKind kind = QualityKind::dropout;
  std::size_t first = 0, last = 0;  // samples affected, inclusive indices
  double start_s = 0.0, end_s = 0.0;  // their time_s (first and last)
  double value = 0.0;          // the evidence's figure, in `unit`
  std::string unit;            // "degC", "s", "deg/h", "sigma", ...
  std::string evidence;        // one sentence: what was seen, with the figure and the threshold
  // clean_run can flag the interval's samples (skipped by the fits, temperatures bridged)
  // and leave a usable run. A lag, an offset, a time unit or a sensor dead over most of the
  // run cannot be cleaned.
  bool cleanable = false;
  // Safe to clean without being asked (a dropout up to QualityOptions::max_bridge_s, a gyro
  // spike): what the fits' bridging and 3-sigma rule would do anyway, said aloud.
  bool clean_by_default = false;
  std::string remedy;          // what the user can do, one sentence
  std::string message() const; // "T1 out_of_range at 1200..1299 s: <evidence>; <remedy>"
};

struct QualityOptions {
  // Physical range of a coil thermistor, degC: a FOG qualification spans -55..+85 degC at most;
  // beyond -60..+130 is a converter's open or short circuit (-273.15: an open NTC), never a coil.
  double min_temp_c = -60.0;
  double max_temp_c = 130.0;
  // A reading repeating exactly for this long while another temperature moves by more than
  // stuck_move_c is stuck. A thermistor with a resolution of 0.01 degC on a 0.005 degC noise
  // changes value every few seconds; a moving coil changes it anyway.
  // "Another temperature moves" is judged lag-aware: each witness (the setpoint, the air, the
  // coil's twin) over the interval shifted back by the thermistor's measured lag behind it
  // (cross-correlation of the rates; the coil's bound when not measurable), and shifted by
  // stuck_lag_margin_s more, the smaller move of the two counting: a coil's centre that stays
  // put for a minute or more at a ramp's start is the coil lagging the air, not a stuck sensor.
  double stuck_min_s = 60.0;
  double stuck_move_c = 0.5;
  double stuck_lag_margin_s = 60.0;
  // Dropouts (NaN not flagged missing) up to this long are bridged by default (the fits
  // interpolate flagged temperatures): at 2 degC/min a linear bridge of 60 s is exact on a ramp
  // and off by at most the curvature at a corner.
  double max_bridge_s = 60.0;
  // White noise of a thermistor (from second differences, robust), degC, over windows of
  // noise_window_s: the simulator's is 0.005 degC, a chamber's air reading 0.02.
  double max_noise_c = 0.05;       // T1, T2
  double max_air_noise_c = 0.2;    // Ta
  double noise_window_s = 300.0;
  // T1 - T2 over the settled parts of holds (both rates under settled_rate_c_per_min for
  // settled_min_s): a uniform coil reads the same on both thermistors.
  double max_offset_c = 0.5;
  double settled_rate_c_per_min = 0.02;
  double settled_min_s = 120.0;
  // Lags of the rates (cross-correlation of d(x), lags -max_lag_scan_s..+max_lag_scan_s) on
  // runs whose T1 rate reaches min_rate_c_per_min. Bounds from the coil's physics
  // (docs/data-quality.md: the outer wall follows the air through the film, the centre follows
  // the wall by radial conduction; measured on the simulator's lumped and distributed coils):
  double min_rate_c_per_min = 0.2;
  double max_lag_scan_s = 400.0;
  // lumped coil: T1 behind T2 38 s, T2 behind Ta 105..116 s; distributed: 86..93 s and
  // 125..187 s (exp1..3, qualification).
  double min_wall_lag_s = -20.0;   // T2 behind Ta, s: the wall cannot lead the air
  double max_wall_lag_s = 360.0;   // T2 behind Ta, s
  double min_core_lag_s = -25.0;   // T1 behind T2, s: the centre cannot lead the wall
  double max_core_lag_s = 130.0;   // T1 behind T2, s
  // With Ta recorded: the centre's lag behind the wall as a share of the wall's behind the
  // air (lumped 0.33..0.37, distributed 0.50..0.69): the wall's film and the coil's radial
  // conduction scale together with the coil's size; a thermistor lagging by a minute moves it
  // past 0.8 (T1) or under 0.2 (T2).
  double min_core_wall_ratio = 0.2;
  // With the setpoint recorded: the air's reading behind the setpoint, s (the simulator's
  // chamber: 43..44 s on exp1..3 and qualification). A chamber's own lag; beyond it the air's reading lags.
  double min_air_lag_s = -20.0;
  double max_air_lag_s = 80.0;
  double max_core_wall_ratio = 0.8;
  // Gyro spikes: beyond spike_sigma robust sigmas of the output about its 31 s running median,
  // at most max_spike_s wide. The simulator's (and a real gyro's) own outliers of about 17
  // sigma are left to the fits' 3-sigma rule; a spike beyond 30 sigma would inflate that rule's
  // own sigma.
  double spike_sigma = 30.0;
  double max_spike_s = 10.0;
  // Saturation: the output repeating exactly for this long at its extreme value.
  double saturation_min_s = 5.0;
  // Checks the options, naming the violated constraint.
  std::expected<void, std::string> validate() const;
};

struct QualityReport {
  std::vector<QualityFlag> flags;  // in order of sensor, then time
  // Figures measured on the way, for reports and tests (NaN when not measured).
  double t1_noise_c = 0.0, t2_noise_c = 0.0;  // median window noise, degC
  double wall_lag_s = 0.0;   // T2 behind Ta (rates' cross-correlation peak), s
  double core_lag_s = 0.0;   // T1 behind T2, s
  double air_lag_s = 0.0;    // Ta behind the setpoint, s
  double hold_offset_c = 0.0;  // median T1 - T2 on settled holds, degC
  bool ok() const { return flags.empty(); }
};

// Every check on one run. Never fails: a run it cannot judge (too short, no ramps for the lag
// check) is judged on what it has.
QualityReport assess_quality(const RunData& run, const QualityOptions& options = {});

// Which flags to clean: those clean_by_default, or every cleanable one.
enum class CleanPolicy { by_default, all };

struct Cleaning {
  RunData run;                        // the run with the cleaned intervals flagged
  std::vector<QualityFlag> cleaned;   // what was cleaned
  std::vector<QualityFlag> remaining; // what was not (refused by the caller, or warned)
  std::vector<std::string> done;      // one sentence per cleaned flag: what was done
};

// A copy of the run with each cleaned flag's samples flagged (out_of_range, or missing for a
// dropout): the fits give them zero weight and bridge the temperatures across them by linear
// interpolation, and Table 1 skips them. Nothing else is changed.
Cleaning clean_run(const RunData& run, const QualityReport& report, CleanPolicy policy);

// A fitted model's coefficients that the run cannot determine, one sentence each: a 1-sigma
// standard error beyond |coef|, a temperature rate too small to excite the rate terms, a run
// whose ramps are shorter than the lag range scanned. Empty when all is identified.
std::vector<std::string> identification_warnings(const Model& m, const RunData& run);

}  // namespace fogbench::model
