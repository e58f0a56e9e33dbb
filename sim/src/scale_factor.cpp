// The simulated gyro's true scale factor and the rate sequence (see fogbench/sim/scale_factor.hpp).
#include "fogbench/sim/scale_factor.hpp"

#include <charconv>
#include <cmath>

namespace fogbench::sim {

double scale_factor(const ScaleFactorTruth& t, double coil_c, double temp_rate_c_per_min) {
  const double d = coil_c - t.t0_c;
  return t.sf0 * (1.0 + 1e-6 * (t.tc_ppm_per_c * d + t.tc2_ppm_per_c2 * d * d + t.temp_rate_ppm_per_c_per_min * temp_rate_c_per_min));
}

double indicated_rate_dps(const ScaleFactorTruth& t, double rate_in_dps, double coil_c, double temp_rate_c_per_min) {
  const double x = rate_in_dps / t.full_scale_dps;
  const double nl = 1.0 + 1e-6 * t.nl_ppm * x * x;
  const double asym = 1.0 + (rate_in_dps > 0.0 ? 0.5 : rate_in_dps < 0.0 ? -0.5 : 0.0) * 1e-6 * t.asymmetry_ppm;
  return scale_factor(t, coil_c, temp_rate_c_per_min) * nl * asym * rate_in_dps;
}

double RateSequence::rate_at(double into_step_s, double step_length_s) const {
  if (rates_dps.empty()) return 0.0;
  auto k = static_cast<std::size_t>(std::floor(std::max(0.0, into_step_s) / step_s));
  const auto whole = static_cast<std::size_t>(std::floor(std::max(0.0, step_length_s) / step_s));
  if (whole >= 1 && k >= whole) k = whole - 1;
  return rates_dps[k % rates_dps.size()];
}

std::expected<RateSequence, std::string> parse_rate_sequence(std::string_view text, double step_s) {
  if (!(std::isfinite(step_s) && step_s > 0.0))
    return std::unexpected("the rate step must be a positive number of seconds, got " + std::to_string(step_s));
  RateSequence seq;
  seq.step_s = step_s;
  std::size_t item = 0;
  while (true) {
    ++item;
    const std::size_t comma = text.find(',');
    std::string_view field = text.substr(0, comma);
    while (!field.empty() && field.front() == ' ') field.remove_prefix(1);
    while (!field.empty() && field.back() == ' ') field.remove_suffix(1);
    if (!field.empty() && field.front() == '+') field.remove_prefix(1);
    double v = 0.0;
    const auto [end, ec] = std::from_chars(field.data(), field.data() + field.size(), v);
    if (field.empty() || ec != std::errc{} || end != field.data() + field.size())
      return std::unexpected("rate " + std::to_string(item) + ": '" + std::string(field) + "' is not a number of deg/s");
    if (!std::isfinite(v) || std::abs(v) > 1000.0)
      return std::unexpected("rate " + std::to_string(item) + ": " + std::string(field) + " deg/s is beyond +-1000 deg/s");
    seq.rates_dps.push_back(v);
    if (comma == std::string_view::npos) break;
    text.remove_prefix(comma + 1);
  }
  return seq;
}

}  // namespace fogbench::sim
