// Scale factor over temperature (issue 29, point 2): from a rate sequence (segments of constant
// commanded input rate, deg/s, with the gyro's output over each) recorded at several
// temperature plateaus, per plateau the bias, the scale factor, its nonlinearity and asymmetry
// by least squares (IEEE Std 952-1997, definitions and annex C), then across plateaus the scale
// factor's temperature sensitivity (ppm/degC), its dependence on the temperature rate
// (ppm per degC/min) and the firmware's model form SF(T) = SF0 (1 + k1 (T - T0) + k2 (T - T0)^2).
// Pure: no I/O. docs/scale-factor.md says what each number is.
#pragma once

#include <cstddef>
#include <expected>
#include <optional>
#include <string>
#include <vector>

#include "fogbench/model/run.hpp"

namespace fogbench::model::sf {

// The samples of a rate sequence, one per row, in time order (columns of equal length).
// The output is the gyro's indicated rate in deg/s, so the scale factor is dimensionless
// (deg/s of output per deg/s of input) and its deviations are in ppm.
struct RateRecord {
  std::vector<double> time_s;       // s, increasing
  std::vector<int> plateau;         // the temperature plateau each sample belongs to (any integer id)
  std::vector<double> rate_in_dps;  // the commanded input rate, deg/s
  std::vector<double> rate_out_dps; // the gyro's output, deg/s
  std::vector<double> coil_c;       // the coil temperature (T1), degC
  std::size_t size() const { return time_s.size(); }
};

struct Options {
  // Seconds dropped at the start of each rate step (the table's acceleration and the gyro's
  // filter settling), s. A step is a run of consecutive samples with the same plateau and
  // the same commanded rate; it is kept from its first sample + settle_s on.
  double settle_s = 5.0;
  double t0_c = 20.0;  // the model form's reference temperature T0, degC
  // The temperature rate term is fitted only when the plateaus' rates span at least this
  // much, degC/min (else it is reported as not identified, with the reason).
  double min_temp_rate_span_c_per_min = 0.05;
  // Empty when valid; else the violated constraint, naming the option.
  std::string validate() const;
};

// One rate step after settling.
struct Step {
  std::size_t index = 0;        // 0-based within its plateau, in time order
  double rate_in_dps = 0.0;
  double start_s = 0.0;         // time of its first sample (before settling), s
  std::size_t n_used = 0;       // samples after settling
  double mean_out_dps = 0.0;    // mean output over them, deg/s
  double mean_coil_c = 0.0;     // mean coil temperature over them, degC
  double residual_ppm_fso = 0.0;// its deviation from the plateau's least-squares line, ppm of full-scale output
};

struct Plateau {
  int id = 0;
  std::vector<Step> steps;
  // The temperature the fitted scale factor refers to: the steps' mean coil temperatures
  // weighted as the slope weights a scale factor that varies from step to step,
  // (r_i - mean r) r_i (their sum is sum (r_i - mean r)^2), degC. Exact for a scale factor
  // linear in temperature; on a hold, the plateau's temperature.
  double coil_c = 0.0;
  // How far the steps' mean coil temperatures spread, degC: on a ramp or an unsettled hold the
  // scale factor changes over the sequence, and the nonlinearity and asymmetry include that.
  double coil_span_c = 0.0;
  double temp_rate_c_per_min = 0.0; // least-squares slope of the coil temperature over the used samples, degC/min
  // The bias: the mean output of the zero-rate steps where the sequence has some, else the
  // line's intercept (bias_from_zero_rate false), deg/h.
  double bias_dph = 0.0;
  bool bias_from_zero_rate = false;
  double scale_factor = 0.0;        // slope of the least-squares line of output vs input, (deg/s)/(deg/s)
  double scale_factor_se = 0.0;     // its 1-sigma standard error from the line's residuals (0 with two rates)
  double full_scale_out_dps = 0.0;  // scale_factor x the largest |input rate|, deg/s
  double nonlinearity_ppm = 0.0;    // max |residual| / full-scale output, ppm (of full-scale output)
  double sf_positive = 0.0;         // slope of the positive inputs through the plateau's bias
  double sf_negative = 0.0;         // slope of the negative inputs through the plateau's bias
  double asymmetry_ppm = 0.0;       // (sf_positive - sf_negative) / their mean, ppm
  std::size_t n_used = 0;           // samples after settling
};

// A coefficient with its 1-sigma standard error, or the reason it is not given.
struct Coefficient {
  std::optional<double> value;
  double se = 0.0;
  std::string not_identified;       // why there is no value (empty when there is one)
};

struct Result {
  Options options;
  std::vector<Plateau> plateaus;    // in the order they first appear
  double sf0 = 0.0;                 // the scale factor at T0 (and zero temperature rate), (deg/s)/(deg/s)
  // Linear fit of the plateaus' scale factors in coil temperature (plus the temperature rate
  // when identified): the temperature sensitivity, ppm/degC, relative to sf0.
  Coefficient tc_ppm_per_c;
  Coefficient temp_rate_ppm_per_c_per_min;  // the scale factor's dependence on the temperature rate, ppm per degC/min
  // The firmware's model form SF(T) = sf0 (1 + k1 (T - T0) + k2 (T - T0)^2), fitted to the
  // plateaus (with the temperature-rate term when identified; the form itself leaves it out):
  Coefficient k1_ppm_per_c;         // k1 x 1e6, ppm/degC
  Coefficient k2_ppm_per_c2;        // k2 x 1e6, ppm/degC^2 (needs three distinct temperatures)
  double model_sf0 = 0.0;           // the model form's SF0 (its own fit's constant)
  double model_rms_ppm = 0.0;       // rms of the plateaus' scale factors about the model form, ppm
  std::size_t n_samples_dropped = 0;// samples dropped by settling
};

// The scale factor of the model form at coil temperature t_c, degC.
double model_scale_factor(const Result& r, double t_c);

// The plateaus of `record` in which the table turned (some commanded rate not 0), in order; the
// others (a ramp, a hold without a rate sequence: at rest throughout) are left out, their rows
// counted in *rows_dropped when given. The CSV path (fogctl scale-factor) and the daemon's
// stored runs (rate_record) select the same plateaus, so a run's exported CSV fits as the
// daemon measured it.
RateRecord turning_plateaus(const RateRecord& record, std::size_t* rows_dropped = nullptr);

// The rate record of a stored run (RunData with rate_in_dps and step): plateau = the profile
// step, rate_out_dps = gyro_dph / 3600, coil_c = T1, as the run's CSV export writes them; the
// settle phase's samples, flagged samples and samples with a non-finite value left out, then
// turning_plateaus. Errors: the run drove no rate table (no rate_in_dps), has no step column,
// or no plateau in which the table turned.
std::expected<RateRecord, std::string> rate_record(const RunData& run);

// Errors name the plateau and step (and the sample's row, 0-based, where about one sample):
// a column of another length, a non-finite value, time not increasing, a step with no sample
// left after settling, a plateau with fewer than two distinct rates, with no positive or no
// negative rate (no asymmetry), a plateau seen again after another one, no plateau at all.
std::expected<Result, std::string> fit(const RateRecord& record, const Options& options = {});

}  // namespace fogbench::model::sf
