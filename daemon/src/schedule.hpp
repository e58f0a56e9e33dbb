// The timing decisions of the acquisition's one schedule (acquisition.hpp), pure: the caller
// passes "now", so they are tested with a fake clock (tests/daemon/schedule_test.cpp). Second k
// is closed at t0 + k periods; the real clock polls at t0 + (k - 1/2) periods (half-period slot
// 2k - 1) and skips ahead when far behind; the paced clock moves t0 forward when a tick is more
// than two periods late. docs/daemon.md, "Acquisition" and "Time scale".
#pragma once

#include <chrono>
#include <cstdint>

namespace fogbench::daemon {

struct Schedule {
  using Clock = std::chrono::steady_clock;

  Clock::time_point t0;                  // tick 0
  std::chrono::nanoseconds half_period;  // half a sample period (0.5 s / time scale)

  std::chrono::nanoseconds period() const { return 2 * half_period; }
  // Half-period slot n: even slots are ticks (slot 2k closes second k), odd ones the real
  // clock's polls (slot 2k - 1 polls for second k).
  Clock::time_point slot_due(std::int64_t n) const { return t0 + n * half_period; }
  Clock::time_point tick_due(std::int64_t k) const { return t0 + k * period(); }

  // The real clock at slot n, woken at `now`: the slot to go on from. More than 20 half-periods
  // behind (the loop was blocked), it skips ahead by an even number of slots, so a poll stays a
  // poll; the ticks in [n, result) are the seconds skipped (stored as not read).
  std::int64_t real_resume_slot(std::int64_t n, Clock::time_point now) const {
    const std::int64_t behind = (now - slot_due(n)) / half_period;
    return behind > 20 ? n + (behind & ~std::int64_t{1}) : n;
  }

  // The paced clock after closing a second, with tick k next: how far t0 moves forward. More
  // than two periods behind (a busy host), the schedule moves back instead of catching up in a
  // burst; otherwise zero.
  std::chrono::nanoseconds paced_shift(std::int64_t k, Clock::time_point now) const {
    const auto late = now - tick_due(k);
    return late > 2 * period() ? std::chrono::duration_cast<std::chrono::nanoseconds>(late) : std::chrono::nanoseconds{0};
  }
};

}  // namespace fogbench::daemon
