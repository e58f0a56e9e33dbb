// Frames of one simulated second; see frames.hpp.
#include "frames.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>

namespace fogbench::mock {

void second_of_counts(double rate_dph, double counts_per_dph, int frames, double noise_dph,
                      std::mt19937_64& rng, std::vector<std::int32_t>& counts) {
  assert(frames >= 1);
  const auto n = static_cast<std::size_t>(frames);
  std::vector<double> noise(n, 0.0);
  if (noise_dph > 0.0) {
    std::normal_distribution<double> draw(0.0, noise_dph);
    double mean = 0.0;
    for (auto& x : noise) {
      x = draw(rng);
      mean += x;
    }
    mean /= static_cast<double>(n);
    // Centred, so the daemon's 1 s average of the frames is the physics' value for the second.
    for (auto& x : noise) x -= mean;
  }
  counts.resize(n);
  constexpr double lo = std::numeric_limits<std::int32_t>::min();
  constexpr double hi = std::numeric_limits<std::int32_t>::max();
  // Error diffusion: frame j carries round(cumulative target) minus what was already sent, so
  // rounding never accumulates over the second.
  double target = 0.0;
  std::int64_t sent = 0;
  for (std::size_t j = 0; j < n; ++j) {
    target += (rate_dph + noise[j]) * counts_per_dph;
    const std::int64_t c = std::llround(std::clamp(target, lo * static_cast<double>(n), hi * static_cast<double>(n))) - sent;
    const auto clamped = static_cast<std::int32_t>(std::clamp<std::int64_t>(c, static_cast<std::int64_t>(lo), static_cast<std::int64_t>(hi)));
    counts[j] = clamped;
    sent += clamped;
  }
}

}  // namespace fogbench::mock
