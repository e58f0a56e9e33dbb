// fogctl's offline commands on CSV files: simulate, fit, verify. Each is a function of its
// options writing to the given streams and returning the exit code, so tests call it directly.
#pragma once

#include <iosfwd>
#include <optional>
#include <string>
#include <vector>

#include "common.hpp"
#include "fogbench/model/noise.hpp"
#include "fogbench/sim/scale_factor.hpp"

namespace CLI {
class App;
}

namespace fogbench::cli {

struct SimulateOptions {
  std::string profile;                 // exp1|exp2|exp3|FILE
  std::vector<std::string> effects;    // extra drift terms with coefficients, e.g. "0.05*T1"
  // A three-axis unit (axes 3): y and z share the housing (its coil, thermistors and drift,
  // effects included) with their own noise, plus each axis's own extra drift, "y=0.05*T1"
  // (repeatable, an axis may take several).
  int axes = 1;
  std::vector<std::string> axis_effects;
  // With axes 3: each axis's coil has its own thermistors (CSV t1_y_c, t2_y_c, t1_z_c, t2_z_c),
  // y's and z's coils sitting deeper in the housing (their air paths 1.6 and 2.4 x x's), so an
  // axis effect may read another axis's coil (T1y, d(T1z)...: a cross-axis term).
  bool axis_thermistors = false;
  std::uint64_t seed = 1;
  std::string output;                  // -o run.csv
  std::string serial = "SIM-0001";
  std::string coil = "distributed";    // distributed|lumped (docs/simulation.md)
  std::string t1_at = "inner", t2_at = "outer";  // the thermistors on a distributed coil
  // The gyro's noise beyond the default AR(2) (unset: the defaults of sim::GyroTruth).
  std::optional<double> arw_deg_per_sqrt_h;      // white innovation: sigma_a = 60 x ARW deg/h
  std::optional<double> bias_instability_dph;    // flicker: Allan floor 0.664 x B
  std::optional<double> rrw_dph_per_sqrt_h;      // rate random walk K
  // Drift that is not thermal (default none): an ageing ramp, deg/h per h of the run, and a
  // periodic disturbance (both of period_s and amplitude_dph, or neither).
  double ageing_dph_per_h = 0.0;
  std::optional<double> periodic_period_s, periodic_amplitude_dph;
  // A rate sequence (deg/s, "0,10,-10,100,-100"), each rate for rate_step_s s, cycled through
  // every profile step: the output is then the rate-sequence CSV (scale_factor.hpp) of a gyro
  // with the true scale factor sf_truth (docs/scale-factor.md). Empty: the ordinary run CSV.
  std::string rate_sequence;
  double rate_step_s = 30.0;
  sim::ScaleFactorTruth sf_truth;
  bool json = false;
  bool quiet = false;
};
int run_simulate(const SimulateOptions& o, std::ostream& out, std::ostream& err);

struct FitCommandOptions {
  std::string run;                     // run.csv
  std::string terms = "paper";         // term list or `paper`
  std::string method;                  // paper|joint (default: paper for `paper`, else joint)
  int max_lag_s = 600;
  bool any_lag = false;  // --any-lag: @auto lags from 0 s, even where firmware cannot compute the term
  double tref_c = 20.0;
  int ar_order = 2;
  std::string output;                  // -o model.json
  bool json = false;
  RunInput input;
};
int run_fit(const FitCommandOptions& o, std::ostream& out, std::ostream& err);

struct VerifyOptions {
  std::string model;
  std::vector<std::string> runs;
  double threshold = 0.2;
  double noise_factor = model::NoiseRule{}.max_noise_factor;   // the second test (model::VerifyOptions)
  double max_fail_s = 60.0;
  bool no_noise_test = false;
  bool json = false;
  RunInput input;
};
int run_verify(const VerifyOptions& o, std::ostream& out, std::ostream& err);

// Registers the offline commands on the app; `code` receives the exit code of the one run.
void add_offline_commands(CLI::App& app, int& code);

}  // namespace fogbench::cli
