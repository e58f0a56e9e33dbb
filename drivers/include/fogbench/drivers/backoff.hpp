// Exponential backoff for reconnecting to a device. Pure: time is passed in, so a test walks an
// hour of retries in microseconds and the daemon's clock stays the only clock.
#pragma once

#include <chrono>
#include <cstdint>

namespace fogbench::drivers {

struct BackoffConfig {
  std::int64_t initial_ms = 250;  // wait after the first failure
  std::int64_t max_ms = 30000;    // the wait never grows past this
  double multiplier = 2.0;        // each further failure multiplies the wait
};

// After a failure no attempt is made until the delay has passed; each consecutive failure
// multiplies the delay, capped; a success resets it. No jitter: one client talks to one device,
// so there is no herd of clients to spread out, and determinism keeps tests exact.
class Backoff {
 public:
  using TimePoint = std::chrono::steady_clock::time_point;

  explicit Backoff(BackoffConfig config = {}) noexcept;

  // True when no failure is pending or its delay has passed.
  bool may_attempt(TimePoint now) const noexcept;
  // Records a failed attempt at `now` and returns the delay before the next attempt.
  std::chrono::milliseconds record_failure(TimePoint now) noexcept;
  void record_success() noexcept;

  // Time left before the next attempt is allowed (0 when it is allowed now).
  std::chrono::milliseconds remaining(TimePoint now) const noexcept;
  int consecutive_failures() const noexcept { return failures_; }
  const BackoffConfig& config() const noexcept { return config_; }

 private:
  BackoffConfig config_;
  int failures_ = 0;
  TimePoint next_attempt_{};
};

}  // namespace fogbench::drivers
