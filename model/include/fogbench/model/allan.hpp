// Allan variance of a gyro's rate output (IEEE Std 952-1997, Annex C): the overlapping Allan
// deviation of a rate series at chosen cluster times, and the noise terms read off its slopes:
// angle random walk (slope -1/2), bias instability (the flat minimum) and rate random walk
// (slope +1/2), each with a confidence interval from its equivalent degrees of freedom. Pure
// functions; a failure is a value.
#pragma once

#include <cstddef>
#include <cstdint>
#include <expected>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "fogbench/model/run.hpp"

namespace fogbench::model::allan {

// One point of the Allan deviation curve.
struct AdevPoint {
  std::int64_t m = 0;     // samples per cluster
  double tau_s = 0.0;     // cluster time, m * tau0_s (s)
  double adev_dph = 0.0;  // overlapping Allan deviation sigma(tau) (deg/h)
  // 1-sigma interval of sigma(tau) per IEEE 952 eq. (C.7): sigma * (1 +- 1/sqrt(2 (N/m - 1))),
  // N the number of samples: K = N/m independent clusters. Conservative for the overlapping
  // estimate, whose variance is smaller; the lower bound is clamped at 0.
  double ci_low_dph = 0.0, ci_high_dph = 0.0;
  std::int64_t terms = 0;  // second differences averaged: N - 2m + 1
};

// Overlapping Allan deviation of rate samples taken every tau0_s seconds, at each cluster size
// m (1 <= m <= (N-1)/2, increasing):
//   theta_k = tau0 * sum_{i<k} rate_i                                   (angle, k = 0..N)
//   AVAR(m) = sum_{k=0}^{N-2m} (theta_{k+2m} - 2 theta_{k+m} + theta_k)^2 / (2 tau^2 (N-2m+1))
// (NIST SP 1065 eq. 14 with phase replaced by angle). Errors name the offending sample/size.
std::expected<std::vector<AdevPoint>, std::string> overlapping_adev(
    std::span<const double> rate_dph, double tau0_s, std::span<const std::int64_t> cluster_sizes);

// Octave cluster sizes 1, 2, 4, ... up to (N-1)/2: the usual "all octave taus".
std::vector<std::int64_t> octave_cluster_sizes(std::size_t n_samples);

// The power-law noise types of a rate (frequency-like) series that the noise terms stand for:
// white rate (white FM: angle random walk), flicker rate (flicker FM: bias instability) and
// random-walk rate (random-walk FM: rate random walk).
enum class NoiseKind { white, flicker, random_walk };

// Equivalent degrees of freedom of the overlapping Allan variance at cluster size m of
// n_samples rate samples, for one noise type: the simple formulas of Howe, Allan and Barnes
// (1981) as NIST SP 1065 (2008) section 5.3.3 / Table 5 gives them, with N = n_samples + 1
// angle (phase) points:
//   white:       [3(N-1)/(2m) - 2(N-2)/N] * 4m^2 / (4m^2 + 5)
//   flicker:     2(N-2)^2 / (2.3N - 4.9) at m = 1, else 5N^2 / (4m(N + 3m))
//   random walk: (N-2) / (m (N-3)^2) * [(N-1)^2 - 3m(N-1) + 4m^2]
// At least 1 (a single second difference is one degree of freedom).
double overlapping_edf(NoiseKind kind, std::int64_t n_samples, std::int64_t m);

// A noise coefficient read off the curve, with its 1-sigma interval and where it was read.
struct NoiseEstimate {
  double value = 0.0, ci_low = 0.0, ci_high = 0.0;  // 68.27 % interval, asymmetric (chi-square)
  double from_tau_s = 0.0, to_tau_s = 0.0;          // the taus used (one: the tau it is read at)
  double edf = 0.0;    // equivalent degrees of freedom of sigma^2 at that tau (noise mix there)
  double share = 0.0;  // this term's share of the fitted sigma^2 at that tau, 0..1
};

// sigma^2(tau) = white / tau + flicker + walk * tau fitted to the curve (see noise_terms), in
// (deg/h)^2 s, (deg/h)^2 and (deg/h)^2 / s, each >= 0, with standard errors from the weighted
// least squares (0 for a part held at 0).
struct AvarFit {
  bool ok = false;
  double white = 0.0, flicker = 0.0, walk = 0.0;
  double white_se = 0.0, flicker_se = 0.0, walk_se = 0.0;
  double part(NoiseKind k, double tau_s) const;  // that part of sigma^2 at tau, (deg/h)^2
  double total(double tau_s) const { return white / tau_s + flicker + walk * tau_s; }
};

// The three noise terms of IEEE 952 Annex C that this curve shows. A term the curve does not
// show is empty with the reason in *_note.
//
// How they are read: sigma^2(tau) = A/tau + F + C tau (white, flicker and random-walk rate) is
// fitted to every tau of the curve by least squares weighted by each point's variance,
// 2 sigma^4 / edf, with A, F, C >= 0 (six rounds, weights and mixed EDF from the round before,
// the measured sigma^2 and white-noise EDF at first). A term is visible when its share of the fitted sigma^2 reaches 1/2 at some tau other
// than the longest and its fitted part exceeds 2 standard errors. It is read at one tau: among
// the taus where its share is >= 1/2, the longest excluded (its EDF is a handful), the one with
// the narrowest relative interval of the term, (interval of sigma^2) / share. There the term's
// part of sigma^2 is the measured sigma^2 less the fitted other parts, and its 1-sigma interval
// is the chi-square interval of the measured sigma^2 (EDF of the noise mix at that tau:
// 1/edf = sum of share_k / edf_k) less the same, widened by the other parts' standard error:
//   sigma^2 in [edf s^2 / chi2_{0.8413}(edf), edf s^2 / chi2_{0.1587}(edf)]  (NIST SP 1065 eq. 45)
struct NoiseTerms {
  // Angle random walk N (deg/sqrt(h)): white part sigma^2 = N^2 / tau, N = sqrt(A (deg/h)^2 s) / 60.
  std::optional<NoiseEstimate> arw_deg_per_sqrt_h;
  // Bias instability B (deg/h): flicker floor sigma = 0.664 B (0.664 = sqrt(2 ln2 / pi)). When
  // no flicker floor is visible but the fitted curve has a minimum inside (the V where white
  // noise meets a rate random walk), sigma_min / 0.664 at that tau is given as an upper bound of
  // B, and the note says so.
  std::optional<NoiseEstimate> bias_instability_dph;
  // Rate random walk K (deg/h/sqrt(h)): random-walk part sigma^2 = K^2 tau / 3, K = 60 sqrt(3 C).
  std::optional<NoiseEstimate> rrw_dph_per_sqrt_h;
  std::string arw_note, bias_instability_note, rrw_note;
  AvarFit fit;
};
NoiseTerms noise_terms(std::span<const AdevPoint> curve);

// Where a run's rate can be analysed: contiguous stretches [begin, end) of samples in a hold
// (every phase when the run records none, and `all_phases`), broken wherever a sample is flagged,
// its gyro value is not finite or the time step differs from the first step by more than 1 %;
// only stretches of at least min_samples. The Allan deviation needs evenly spaced samples, and a
// ramp's thermal drift would show as rate random walk.
struct Stretch {
  std::size_t begin = 0, end = 0;  // sample indices, end exclusive
  Phase phase = Phase::unknown;    // hold, or unknown when the run records no phase
  double tau0_s = 1.0;             // the sample interval, s
};
std::vector<Stretch> even_stretches(const RunData& run, std::size_t min_samples, bool all_phases = false);

}  // namespace fogbench::model::allan
