// The gyro frames of one simulated second: the second's rate spread over its frames with
// zero-mean per-frame noise, quantised so the counts add up to the second's rate exactly (to one
// count over the whole second). Pure: the caller sends them.
#pragma once

#include <cstdint>
#include <random>
#include <vector>

namespace fogbench::mock {

// Replaces `counts` with `frames` values (frames >= 1). `counts_per_dph` is the counts of one
// frame per deg/h; `noise_dph` the per-frame noise (1 sigma, deg/h; 0 for none). The noise is
// centred over the second, and the quantisation carries its remainder from frame to frame, so
// sum(counts) == llround(frames * rate_dph * counts_per_dph) (up to rounding of the centred noise
// sum, below 1e-9 counts) and each frame is within one count of its noisy value.
void second_of_counts(double rate_dph, double counts_per_dph, int frames, double noise_dph,
                      std::mt19937_64& rng, std::vector<std::int32_t>& counts);

}  // namespace fogbench::mock
