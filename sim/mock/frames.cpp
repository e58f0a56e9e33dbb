// A gyro streaming frames at its frame rate; see frames.hpp.
#include "frames.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>

namespace fogbench::mock {

GyroStream::GyroStream(StreamParams params) : p_(std::move(params)) {
  assert(p_.frame_rate_hz >= 1);
  assert(p_.warmup_tau_s > 0);
  history_.assign(std::max<std::size_t>(1, p_.ar.size()) * static_cast<std::size_t>(p_.frame_rate_hz), 0.0);
  power_on(0.0);
}

void GyroStream::power_on(double t_s) {
  // A gyro that starts: its noise filter, quantiser and counter start afresh.
  std::fill(history_.begin(), history_.end(), 0.0);
  at_ = 0;
  carry_counts_ = 0;
  spike_left_ = 0;
  sequence_ = 0;
  powered_ = true;
  on_since_s_ = t_s;
}

void GyroStream::second(std::int64_t second_s, double drift_dph, const PowerWindow& power, std::mt19937_64& rng,
                        std::vector<StreamFrame>& out) {
  const auto n = static_cast<std::size_t>(p_.frame_rate_hz);
  const double innovation_dph = p_.sigma_a_dph * std::sqrt(static_cast<double>(n));
  std::normal_distribution<double> unit_normal(0.0, 1.0);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  const double spike_per_frame = p_.outlier_rate_per_s / static_cast<double>(n);
  out.resize(n);
  double sum_dph = 0;
  std::size_t powered_frames = 0;
  for (std::size_t j = 0; j < n; ++j) {
    const double t_s = static_cast<double>(second_s) + static_cast<double>(j) / static_cast<double>(n);
    auto& f = out[j];
    if (!power.powered_at(t_s)) {
      powered_ = false;
      f = StreamFrame{};
      continue;
    }
    if (!powered_) power_on(t_s);
    // Seasonal AR: the lags are whole seconds (multiples of N frames).
    double y = innovation_dph * unit_normal(rng);
    for (std::size_t i = 0; i < p_.ar.size(); ++i) {
      const std::size_t back = (i + 1) * n;
      y += p_.ar[i] * history_[(at_ + history_.size() - back) % history_.size()];
    }
    history_[at_] = y;
    at_ = (at_ + 1) % history_.size();
    if (spike_left_ == 0 && spike_per_frame > 0 && uniform(rng) < spike_per_frame) {
      spike_left_ = static_cast<int>(n);
      spike_dph_ = (uniform(rng) < 0.5 ? -1.0 : 1.0) * p_.outlier_dph;
    }
    double value = drift_dph + y;
    if (spike_left_ > 0) {
      value += spike_dph_;
      --spike_left_;
    }
    if (p_.white_dph > 0) value += p_.white_dph * unit_normal(rng);
    if (p_.warmup_dph != 0) value += p_.warmup_dph * std::exp(-(t_s - on_since_s_) / p_.warmup_tau_s);
    sum_dph += value;
    ++powered_frames;
    // Error diffusion across frames: rounding never accumulates.
    constexpr double lo = std::numeric_limits<std::int32_t>::min(), hi = std::numeric_limits<std::int32_t>::max();
    const double target = std::clamp(value * p_.counts_per_dph + carry_counts_, lo, hi);
    const double c = std::nearbyint(target);
    carry_counts_ = std::clamp(target - c, -1.0, 1.0);
    f.counts = static_cast<std::int32_t>(c);
    f.sequence = sequence_++;
    f.powered = true;
    f.warming_up = t_s - on_since_s_ < p_.startup_flag_s;
  }
  last_mean_dph_ = powered_frames > 0 ? sum_dph / static_cast<double>(powered_frames) : std::nan("");
}

}  // namespace fogbench::mock
