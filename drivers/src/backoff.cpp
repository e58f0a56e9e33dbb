// Exponential reconnection backoff with injected time.
#include "fogbench/drivers/backoff.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>

namespace fogbench::drivers {

Backoff::Backoff(BackoffConfig config) noexcept : config_(config) {
  assert(config_.initial_ms > 0 && config_.max_ms >= config_.initial_ms && config_.multiplier >= 1.0);
}

bool Backoff::may_attempt(TimePoint now) const noexcept {
  return failures_ == 0 || now >= next_attempt_;
}

std::chrono::milliseconds Backoff::record_failure(TimePoint now) noexcept {
  // initial * multiplier^(n-1) for the n-th consecutive failure, computed in double and capped
  // before converting so a long outage cannot overflow.
  const double delay = static_cast<double>(config_.initial_ms) *
                       std::pow(config_.multiplier, static_cast<double>(failures_));
  const auto delay_ms = static_cast<std::int64_t>(
      std::min(delay, static_cast<double>(config_.max_ms)));
  if (failures_ < 1000) ++failures_;
  next_attempt_ = now + std::chrono::milliseconds(delay_ms);
  return std::chrono::milliseconds(delay_ms);
}

void Backoff::record_success() noexcept { failures_ = 0; }

std::chrono::milliseconds Backoff::remaining(TimePoint now) const noexcept {
  if (may_attempt(now)) return std::chrono::milliseconds(0);
  return std::chrono::ceil<std::chrono::milliseconds>(next_attempt_ - now);
}

}  // namespace fogbench::drivers
