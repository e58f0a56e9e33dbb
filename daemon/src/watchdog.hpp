// systemd's watchdog fed from the event loop (an internal header of daemon/src/, used by main.cpp):
// WATCHDOG=1 is sent only while the loop runs what is posted to it, so a loop stuck in a handler
// (a resume's gap written on it was the case of issue 27, point 2: one ping in 75 s) stops the
// pings and systemd restarts the daemon (WatchdogSec= in the units). docs/reliability.md.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <functional>
#include <memory>
#include <mutex>
#include <thread>
#include <utility>

namespace fogbench::daemon {

// The rule, without a thread or a clock: each round pings when the task posted to the loop at the
// round before has run (the first round pings: the loop has just started), then posts the next.
// A loop that runs nothing more gets one ping at most after its last task.
class LoopWatchdogRounds {
 public:
  using Post = std::function<void(std::function<void()>)>;  // runs a task on the loop, later
  using Ping = std::function<void()>;                        // WATCHDOG=1
  LoopWatchdogRounds(Post post, Ping ping) : post_(std::move(post)), ping_(std::move(ping)) {}

  void round() {
    if (alive_->exchange(false)) ping_();
    // The flag is shared with the task: a task the loop runs after this object is gone is harmless.
    post_([alive = alive_] { alive->store(true); });
  }

 private:
  Post post_;
  Ping ping_;
  std::shared_ptr<std::atomic<bool>> alive_ = std::make_shared<std::atomic<bool>>(true);
};

// The rounds on a thread of their own, at half systemd's interval, until destroyed.
class LoopWatchdog {
 public:
  LoopWatchdog(LoopWatchdogRounds::Post post, LoopWatchdogRounds::Ping ping, std::chrono::microseconds interval)
      : rounds_(std::move(post), std::move(ping)) {
    thread_ = std::thread([this, half = interval / 2] {
      std::unique_lock lock(mutex_);
      while (!cv_.wait_for(lock, half, [this] { return stop_; })) rounds_.round();
    });
  }
  LoopWatchdog(const LoopWatchdog&) = delete;
  LoopWatchdog& operator=(const LoopWatchdog&) = delete;
  ~LoopWatchdog() {
    {
      std::lock_guard lock(mutex_);
      stop_ = true;
    }
    cv_.notify_all();
    thread_.join();
  }

 private:
  LoopWatchdogRounds rounds_;
  std::mutex mutex_;
  std::condition_variable cv_;
  bool stop_ = false;
  std::thread thread_;
};

}  // namespace fogbench::daemon
