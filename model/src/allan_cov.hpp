// Internal: the covariance of overlapping Allan variance estimates under the noise laws the
// floor reads (white rate, flicker, rate random walk), for tests that count the Allan points'
// degrees of freedom as the estimates are correlated (noise.cpp, the walk's test).
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

namespace fogbench::model::detail {

// Allan variance AVAR(m) = white / m + flicker + walk m at cluster size m (samples of 1 s),
// (deg/h)^2: white the rate's variance at 1 s (angle random walk), flicker 2 ln2 h_-1, walk
// (2 pi^2 / 3) h_-2 per s. Each >= 0.
struct AvarLaws {
  double white = 0.0, flicker = 0.0, walk = 0.0;
  double at(std::int64_t m) const;
};

// The covariance of the overlapping Allan variance estimates at cluster sizes ms (samples) over
// one record of len samples of Gaussian rate noise under law, (deg/h)^4: ms.size()^2 values,
// row-major. Each estimate is the mean of len - 2m + 1 squared second differences of the angle
// over 2; sizes with 2m >= len give zero rows. Exact for white noise and the random walk on
// 1 s samples (up to the walk's discrete-time correction, a white term walk / (2 m) in AVAR),
// the flicker as continuous-time 1/f noise.
std::vector<double> overlapping_avar_cov(const AvarLaws& law, std::span<const std::int64_t> ms, std::size_t len);

// The equivalent degrees of freedom of one overlapping Allan variance estimate, 2 E^2 / Var:
// what a chi-square of that many degrees of freedom spreads as (Greenhall's and Howe's edf).
double overlapping_avar_edf(const AvarLaws& law, std::int64_t m, std::size_t len);

}  // namespace fogbench::model::detail
