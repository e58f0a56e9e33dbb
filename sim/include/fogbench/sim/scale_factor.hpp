// The simulated gyro's true scale factor (issue 29, point 2): what a rate table's input rate
// becomes in the gyro's output, with a temperature dependence, a temperature-rate dependence,
// a cubic nonlinearity and an asymmetry, so that model::sf::fit is tested against known values
// (docs/scale-factor.md). And the rate sequence a simulated run commands: a list of rates
// cycled through each profile step, until the rate table device (issue 29, point 1) exists.
#pragma once

#include <expected>
#include <string>
#include <string_view>
#include <vector>

namespace fogbench::sim {

struct ScaleFactorTruth {
  double sf0 = 1.0;                        // (deg/s of output) / (deg/s of input) at t0_c, at rest thermally
  double t0_c = 20.0;                      // reference coil temperature, degC
  double tc_ppm_per_c = 15.0;              // first-order temperature coefficient, ppm/degC
  double tc2_ppm_per_c2 = 0.0;             // second-order temperature coefficient, ppm/degC^2
  double temp_rate_ppm_per_c_per_min = 0.0;// dependence on the coil's temperature rate, ppm per degC/min
  // Cubic nonlinearity: the local scale factor at input r is sf (1 + nl_ppm 1e-6 (r / full_scale_dps)^2).
  double nl_ppm = 0.0;
  double full_scale_dps = 300.0;           // deg/s
  // Asymmetry: positive inputs see sf (1 + asym/2), negative sf (1 - asym/2), asym = asymmetry_ppm 1e-6.
  double asymmetry_ppm = 0.0;
};

// The scale factor of `t` at coil temperature coil_c (degC) and temperature rate (degC/min).
double scale_factor(const ScaleFactorTruth& t, double coil_c, double temp_rate_c_per_min);
// The output (deg/s) for input rate_in_dps, without the bias: scale factor x nonlinearity x asymmetry x input.
double indicated_rate_dps(const ScaleFactorTruth& t, double rate_in_dps, double coil_c, double temp_rate_c_per_min);

// A rate sequence: the rates (deg/s) commanded in turn, each for step_s seconds, cycled from
// the start of every profile step.
struct RateSequence {
  std::vector<double> rates_dps;
  double step_s = 30.0;
  // The commanded rate at `into_step_s` seconds after the profile step began, in a profile step
  // `step_length_s` long, deg/s. The profile step's tail shorter than a rate step stays at the
  // rate before it (a longer last rate step), so that no rate step is cut to a few samples.
  double rate_at(double into_step_s, double step_length_s) const;
};
// Parses "0,10,-10,100,-100" (deg/s, comma-separated, each |r| <= 1000 deg/s); step_s > 0 s.
// Errors name the item (1-based) and what is wrong.
std::expected<RateSequence, std::string> parse_rate_sequence(std::string_view text, double step_s);

}  // namespace fogbench::sim
