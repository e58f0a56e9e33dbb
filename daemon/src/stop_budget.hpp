// fogbenchd's stop under one budget (an internal header of daemon/src/, used by server.cpp): the
// share of each step of a stop, and the guard that ends the process when the whole budget is
// spent, so that a stop completes within systemd's TimeoutStopSec (20 s in the units) whatever a
// device, the store or the plant does. docs/reliability.md "The stop's budget".
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdlib>
#include <mutex>
#include <string>
#include <thread>

#include <spdlog/spdlog.h>

namespace fogbench::daemon {

namespace stop_budget {
using namespace std::chrono_literals;
// The whole stop, from the signal to the process's exit: below TimeoutStopSec=20 with room for
// the process's own exit and a loaded host.
inline constexpr auto kTotal = 15s;
// The run's end: its last samples committed (Station::kStopSampleDrainTimeout, 4 s), on the loop.
// The chamber to its safe setpoint, confirmed: at most this long.
inline constexpr auto kSafeSetpoint = 5s;
// The plant link, told at the signal (in parallel with the steps above): a run being sent has
// this long to commit, then its transaction is abandoned, and the thread this long more to end.
inline constexpr auto kPlantGrace = 3s;
inline constexpr auto kPlantAfterAbandon = 2s;
// A running analysis job (a fit, the workbench) after the loop: then abandoned.
inline constexpr auto kAnalysis = 2s;
// The sample writer after the loop (the run's end drained it already: this is a last guard).
inline constexpr auto kSampleWriter = 2s;
}  // namespace stop_budget

// Armed at the start of a stop; ends the process with status 1 when the stop is still going
// `budget` later, naming the step it was in. Disarmed (and joined) when the stop is done.
class StopGuard {
 public:
  StopGuard() = default;
  StopGuard(const StopGuard&) = delete;
  StopGuard& operator=(const StopGuard&) = delete;
  ~StopGuard() { disarm(); }

  void arm(std::chrono::steady_clock::duration budget) {
    if (thread_.joinable()) return;
    began_ = std::chrono::steady_clock::now();
    thread_ = std::thread([this, budget] {
      std::unique_lock lock(mutex_);
      if (cv_.wait_for(lock, budget, [this] { return done_; })) return;
      spdlog::critical("stopping: the stop's budget of {:.0f} s is spent in step '{}': exiting now (status 1) "
                       "without the steps left; what the store committed is kept",
                       std::chrono::duration<double>(budget).count(), step_);
      spdlog::default_logger()->flush();
      std::_Exit(1);
    });
  }
  // Names the step in progress (for the guard's last line) and logs how long the previous took.
  void step(const std::string& name) {
    const auto now = std::chrono::steady_clock::now();
    std::lock_guard lock(mutex_);
    if (!step_.empty() && step_ != name)
      spdlog::info("stopping: {} took {:.2f} s", step_, std::chrono::duration<double>(now - step_began_).count());
    step_ = name;
    step_began_ = now;
  }
  double elapsed_s() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - began_).count();
  }
  std::chrono::steady_clock::time_point began() const { return began_; }
  void disarm() {
    {
      std::lock_guard lock(mutex_);
      done_ = true;
    }
    cv_.notify_all();
    if (thread_.joinable()) thread_.join();
  }

 private:
  std::mutex mutex_;
  std::condition_variable cv_;
  bool done_ = false;
  std::string step_;
  std::chrono::steady_clock::time_point began_{}, step_began_{};
  std::thread thread_;
};

}  // namespace fogbench::daemon
