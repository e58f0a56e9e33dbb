// The gyro's own noise as the yardstick of a model's error. A real FOG's noise is more than
// the AR(2) innovation the paper fits on its opening hold: flicker (bias instability) and rate
// random walk wander slowly, so over a run of hours they add error that no thermal term
// explains and AR(2) whiteness calls a missing effect. The noise floor is read where the
// temperature holds still (the model's residual over the settled holds), as an Allan curve
// fitted with three noise laws, and gives what a run's residual may be when the model is
// right: its std over the run, the std of its smoothed values, and how far a realisation
// may stray from them. Pure; docs/workbench.md "The noise floor".
#pragma once

#include <cstddef>
#include <expected>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "fogbench/model/allan.hpp"
#include "fogbench/model/run.hpp"

namespace fogbench::model {

struct NoiseFloorOptions {
  // A hold counts from this long after the last ramp, s: the coil still settles after a ramp,
  // and a thermal term the model misses (a second path delayed up to the lags searched, 600 s)
  // still moves the residual there, which would read as slow noise and excuse itself. The
  // run's first hold counts whole (the chamber was stable before the run).
  double settle_s = 600.0;
  std::size_t min_stretch_s = 120;  // shorter settled stretches are not used, s
  // A slow law (flicker, random walk) is kept only when it lowers the curve's weighted misfit
  // (chi-square with each point's degrees of freedom) by this much: 4 sigma for one parameter.
  // The long taus rest on a few clusters whose scatter is skewed: at 9 a flicker's scatter at
  // 128..256 s read as a rate random walk of 0.28 deg/h/sqrt(h) (twice the noise std over a
  // run), at 16 not, while a walk of 0.1 deg/h/sqrt(h) in 20 min holds is still seen.
  double min_chi2_gain = 16.0;
  // Regress the thermistors' creep (T1, T2 levels and rates) out of the hold residual before the
  // curve is read, when significant: a Wald test at 99.9 % whose variance is the floor's own
  // noise (noise.cpp, remove_creep). On: it raised no false alarm more than off on the
  // workbench's noise suites and brings the distributed coil's seed 71 closer to its floor.
  // docs/workbench.md "The noise floor".
  bool remove_creep = true;
  // The rate random walk the holds cannot exclude, when flicker and no walk is seen: the largest
  // walk whose profile deviance of the Allan curve rises by at most this above its least (0: not
  // bounded; 4 is about a 2 sigma one-sided bound). The rule allows
  // for it in its limits (yardstick). docs/workbench.md "Real FOG noise: where the floor is blind".
  double walk_bound_chi2 = 4.0;
  // A rate random walk read off the whole curve is kept only when, on the curve's last six
  // octaves (tau >= the longest / 64, where a walk is identifiable), the laws refitted there
  // with a free walk lower the deviance by at least this against the same laws without one (a
  // likelihood-ratio test of one parameter held >= 0, its gain scaled for the Allan points'
  // correlation (NoiseFloor::walk_test_dof_scale): 4 is about 2.3 % under no walk), or the
  // walk as read fits those taus no worse than no walk. docs/workbench.md "The noise floor".
  double walk_min_gain = 4.0;
  // ... or when the walk as read (held at its value, the other laws refitted there) lowers that
  // deviance by at least this, in the same scaled units. 0: it fits them no worse than no walk.
  // 1 reads fewer walks off flat flicker curves (3 -> 2 of 40) but loses real ones (docs/
  // workbench.md "Walks read off flat curves").
  double walk_read_min_gain = 0.0;
};

// One-sided power spectral density of the floor at 1 s samples, (deg/h)^2/Hz:
//   S(f) = S_fast(f) + flicker_h / f + walk_h / f^2,
// S_fast the model's AR(p) with its sigma_a (2 sigma_a^2 / |1 - sum k_i e^{-2 pi i f i}|^2)
// when no slow noise is seen, else the white level read off the holds (2 white_var_dph2).
struct NoiseFloor {
  std::vector<double> ar;               // the model's AR coefficients k_1..k_p
  double sigma_a_dph = 0.0;             // the model's innovation std, deg/h
  // With slow noise: the white (angle random walk) variance read off the curve at 1 s,
  // (deg/h)^2, which then stands for the short-term part (0: the model's AR noise does).
  double white_var_dph2 = 0.0;
  double flicker_h = 0.0;               // (deg/h)^2: Allan variance 2 ln2 h
  double walk_h = 0.0;                  // (deg/h)^2/s: Allan variance (2 pi^2 / 3) h tau
  double bias_instability_dph = 0.0;    // B = sqrt(pi h_-1), deg/h (Allan floor 0.664 B)
  double rrw_dph_per_sqrt_h = 0.0;      // K = 60 sqrt(3 AVAR/tau), deg/h/sqrt(h)
  // When no walk is seen: the largest the holds cannot exclude ((deg/h)^2/s, as walk_h; and as
  // K, deg/h/sqrt(h)). Not part of the floor's laws (psd, variances): the rule's limits only.
  double walk_bound_h = 0.0;
  double rrw_bound_dph_per_sqrt_h = 0.0;
  // The walk's test on the curve's last six octaves (NoiseFloorOptions::walk_min_gain): how much
  // a free walk lowered the deviance there (0: it came out 0, or no walk was asked of the holds).
  double walk_test_gain = 0.0;
  // The scale on that gain for the Allan points' correlation, already applied to it: the walk's
  // score variance as the deviance counts it (each point independent, half its N / m - 1
  // degrees of freedom) over its variance under the estimates' covariance under the null law
  // (about 0.6 under flicker in 30 min holds, 1 to 1.5 under white noise; 1 when not computed).
  double walk_test_dof_scale = 1.0;
  // When a walk is read off the whole curve: how much that walk, held as read, lowers the long
  // taus' deviance (the other laws refitted there), in the same scaled units (negative: it fits
  // them worse than no walk).
  double walk_read_gain = 0.0;
  std::size_t hold_samples = 0;         // settled hold samples the curve was read on
  std::size_t stretches = 0;
  double longest_tau_s = 0.0;           // the longest cluster time of the curve, s
  std::vector<allan::AdevPoint> curve;  // the holds' pooled Allan deviation of the residual
  std::string note;                     // how it was read, or why the AR noise alone is used
  // The part of the holds' residual that follows the thermistors' creep (T1, T2 levels and
  // rates) was taken out before the curve was read: it was significant (creep_chi2, a Wald
  // chi-square of creep_dof degrees of freedom under no creep, above its 99.9 % quantile, the
  // variance the floor's own noise). docs/workbench.md "The noise floor".
  bool creep_removed = false;
  double creep_chi2 = 0.0;              // that Wald statistic (0: not tested, or no thermistor moved)
  std::size_t creep_dof = 0;            // its degrees of freedom (0: not tested)
  bool measured() const { return hold_samples > 0; }
  bool slow() const { return flicker_h > 0.0 || walk_h > 0.0; }
};

// The floor of a run's residual (measured - predicted, deg/h; weights 0 for unusable samples),
// read over the run's settled holds. Too few hold samples: the model's AR noise alone, said in
// the note. ar and sigma_a_dph are the model's.
NoiseFloor estimate_noise_floor(const RunData& run, std::span<const double> residual_dph, std::span<const double> weight,
                                std::span<const double> ar, double sigma_a_dph, const NoiseFloorOptions& o = {});
// The floor of one unit read over several runs' settled holds at once (the same gyro: more
// hold time, longer taus, a steadier reading of its slow noise).
struct FloorRun {
  const RunData* run = nullptr;
  std::span<const double> residual_dph, weight;
};
NoiseFloor estimate_noise_floor(std::span<const FloorRun> runs, std::span<const double> ar, double sigma_a_dph,
                                const NoiseFloorOptions& o = {});

// What the floor lets a run's residual be, over `samples` 1 s samples with the run's mean
// removed, after a centred moving average of smooth_s samples (1: none). Variances in (deg/h)^2:
// `total` the expected variance, `slow` the part of it that flicker and random walk make,
// `slow_q99` the 99th percentile of that part over realisations (a weighted sum of exponential
// periodogram ordinates, matched by a gamma law in mean and variance: a random walk's variance
// over one run is dominated by a few ordinates and strays far from its mean).
struct FloorVariance {
  double total = 0.0, slow = 0.0, slow_q99 = 0.0;
};
FloorVariance floor_variance(const NoiseFloor& f, std::size_t samples, int smooth_s = 1);

// The variance the floor's slow part (flicker, random walk) gives a linear statistic
// sum_i c_i x_i of consecutive 1 s samples, (deg/h)^2: int S_slow(f) |C(f)|^2 df. Finite when
// the weights are blind to a constant and a line (sum c_i = sum i c_i = 0), as a step
// estimated beside a line is.
double floor_slow_variance(const NoiseFloor& f, std::span<const double> c);

// The floor's one-sided power spectral density at f_hz (1 s samples), (deg/h)^2/Hz: S(f) above.
double floor_psd(const NoiseFloor& f, double f_hz);

// The Allan variance the floor gives at cluster time tau_s, (deg/h)^2.
double floor_avar(const NoiseFloor& f, double tau_s);

// What the whiteness test's RMS of the autocorrelation may exceed its white-noise allowance by
// on a run of `samples` samples: the slow noise's 99th-percentile share of the run's variance
// (flicker, random walk, and the walk the holds cannot exclude); 0 with no slow noise seen.
// The rule's (Yardstick::acf_allowance) is this, computed once by the yardstick.
double slow_acf_allowance(const NoiseFloor& f, std::size_t samples);

// The floor with the walk the holds cannot exclude (walk_bound_h) added to its laws as if seen,
// the bound itself cleared: what the rule's limits are computed on (yardstick).
NoiseFloor with_walk_bound(const NoiseFloor& f);

// What a limit of the rule allows for beyond the floor as read, for its message: ", allowing
// for a rate random walk up to K deg/h/sqrt(h) that the holds cannot exclude", or "".
std::string allowance_note(const NoiseFloor& f);

// The noise factor's reason, one sentence for every place that judges it (verify, diagnose's
// checks): "compensated std C deg/h is F x the gyro's noise std N deg/h (at most L x[, allowing
// for ...])"; C and N in deg/h, F and L ratios.
std::string noise_factor_reason(double comp_std_dph, double noise_std_dph, double factor, double limit_factor, const NoiseFloor& f);

// The one rule that asks whether what a model leaves on a run is the gyro's own noise, shared
// by verify's second test, compare's failing intervals and diagnose's adequacy checks.
struct NoiseRule {
  // Compensated std at most this times the floor's std over the run: a misfit of about 0.75 x
  // the noise std is let through (sqrt(1.25^2 - 1)); an effect left at the size of the noise
  // (sqrt(2) = 1.41 x) is not. Where the floor's slow noise can stray further over one run
  // (its 99th percentile), that is the limit instead.
  double max_noise_factor = 1.25;
  // A failing interval: the residual's centred smooth_s average beyond the threshold
  //   sqrt((k_sigma sigma_a)^2 + k_slow^2 var_slow(smoothed))
  // for max_fail_s or more. k_sigma sigma_a is the paper's short-term band. k_slow 7 is the 99th
  // percentile of a random walk's largest excursion from where the run's model put its level
  // (a held-out run's mu0 is the fit run's; the walk does not return to it): P(max |W| > a) <=
  // 4 (1 - Phi(a / sqrt(T))) gives a = 2.81 sqrt(T), against its demeaned std sqrt(T / 6).
  double k_sigma = 3.0;
  double k_slow = 7.0;
  int smooth_s = 61;
  double max_fail_s = 60.0;
  bool read_floor = true;            // false: the model's AR noise alone (the rule before the floor)
  NoiseFloorOptions floor;
  // The floor already read for this model, e.g. over all the unit's runs (model.hpp's
  // unit_noise_floor): used instead of reading one off the run being judged.
  std::optional<NoiseFloor> given;
  std::expected<void, std::string> validate() const;
};

// The rule's limits on one run, computed once (yardstick) and read by every verdict through
// verify's Verification: verify's second test, compare's failing intervals, diagnose's adequacy.
struct Yardstick {
  NoiseFloor floor;
  double noise_std_dph = 0.0;        // the floor's std over the run, deg/h
  double limit_factor = 0.0;         // the compensated std allowed, over noise_std
  double threshold_dph = 0.0;        // a failing interval's threshold on the smoothed residual, deg/h
  // What the whiteness test's RMS of the autocorrelation may exceed its white-noise allowance
  // by (slow_acf_allowance; 0 with no slow noise seen).
  double acf_allowance = 0.0;
  // When the floor shows slow noise but no walk: the three limits above allow for the walk the
  // holds cannot exclude (NoiseFloor::walk_bound_h): the threshold and the whiteness allowance
  // as for a seen walk (on the floor with_walk_bound), the noise factor's limit by its mean
  // variance over the run on top; these are the limits without it.
  bool walk_allowance = false;
  double limit_factor_seen = 0.0, threshold_seen_dph = 0.0, acf_allowance_seen = 0.0;
};
Yardstick yardstick(const RunData& run, std::span<const double> residual_dph, std::span<const double> weight,
                    std::span<const double> ar, double sigma_a_dph, std::size_t samples, const NoiseRule& rule = {});

}  // namespace fogbench::model
