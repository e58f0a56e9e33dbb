// Allan variance of a gyro's rate output (IEEE Std 952-1997, Annex C): the overlapping Allan
// deviation of a rate series at chosen cluster times, and the noise terms read off its slopes:
// angle random walk (slope -1/2), bias instability (the flat minimum) and rate random walk
// (slope +1/2), each with a confidence interval. Pure functions; a failure is a value.
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

// A noise coefficient read off the curve, with its 1-sigma interval and where it was read.
struct NoiseEstimate {
  double value = 0.0, ci_low = 0.0, ci_high = 0.0;
  double from_tau_s = 0.0, to_tau_s = 0.0;  // the taus used
};

// The three noise terms of IEEE 952 Annex C that this curve shows. A term the curve does not
// show is empty with the reason in *_note (for example "no minimum: sigma still falls at the
// longest tau, 4096 s").
struct NoiseTerms {
  // Angle random walk N (deg/sqrt(h)): sigma(tau) = N / sqrt(tau). A line of slope -1/2 through
  // the points where the local slope is -1/2 +- 1/4, from the shortest tau over at most a decade,
  // read at tau = 1 s: N = sigma(1 s) * sqrt(1 s) = sigma(1 s in deg/h) / 60 deg/sqrt(h).
  std::optional<NoiseEstimate> arw_deg_per_sqrt_h;
  // Bias instability B (deg/h): the flat minimum of sigma over 0.664 (sqrt(2 ln2 / pi)); from/to
  // give the flat stretch (sigma within 1.2 sigma_min). A minimum that is not flat over a factor 8
  // of tau (the V where white noise meets a rate random walk) still gives sigma_min / 0.664, an
  // upper bound of B, and says so in the note.
  std::optional<NoiseEstimate> bias_instability_dph;
  // Rate random walk K (deg/h/sqrt(h)): sigma(tau) = K sqrt(tau/3); a line of slope +1/2
  // through the points after the minimum where the slope is +1/2 +- 1/4.
  std::optional<NoiseEstimate> rrw_dph_per_sqrt_h;
  std::string arw_note, bias_instability_note, rrw_note;
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
