// fogbenchd's link to the plant store (issue 14; an internal header of daemon/src/, used by
// server.cpp): a thread of its own, with its own connection to the bench's store, that takes the
// outbox's entries in order and replicates each run to PostgreSQL (fogbench::plant). It never
// touches the loop: acquisition does not wait for the plant, and an outage only grows the outbox.
//
// Stopping is bounded whatever the plant's server does: a run being sent gets a grace to commit,
// then its transaction is abandoned by shutting the connection's socket (the server rolls it back;
// the run stays at the outbox's head and is sent again at the next start, replacing whatever the
// plant held for it).
#pragma once

#include <chrono>
#include <condition_variable>
#include <filesystem>
#include <mutex>
#include <thread>

#include "fogbench/daemon/config.hpp"
#include "plant_activity.hpp"

namespace fogbench::daemon {

class PlantLink {
 public:
  using Clock = std::chrono::steady_clock;

  PlantLink(PlantConfig config, std::filesystem::path store_path);
  ~PlantLink();
  PlantLink(const PlantLink&) = delete;
  PlantLink& operator=(const PlantLink&) = delete;

  // Tells the thread to stop: between runs it ends at once, a run being sent is finished first.
  void request_stop();
  // Stops: waits until `abandon_at` for the thread to end, then abandons the transaction in
  // progress (logged: which run, for how long, how long without progress) and waits until
  // `give_up_at`. True when the thread ended and was joined; false leaves it running (blocked
  // where no socket can be shut, e.g. in a DNS look-up), for the process's end to take.
  bool stop(Clock::time_point abandon_at, Clock::time_point give_up_at);
  // stop() with the default grace: 3 s to commit, 2 s more after an abandon.
  bool stop();

  // What the link is doing, for `status.plant` (stalled after config.stall_s without progress).
  PlantLinkState state() const;

 private:
  void run();
  bool wait(double seconds);  // false when stopping
  void set_phase(PlantActivity::Phase phase, std::int64_t run_id = 0);
  void abandon();  // shuts the plant connection's socket, under mutex_

  PlantConfig config_;
  std::filesystem::path store_path_;
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  bool stopping_ = false;
  bool ended_ = false;       // run() has returned
  int abort_fd_ = -1;        // a dup of the plant connection's socket while one is open
  PlantActivity activity_;
  std::thread thread_;
};

}  // namespace fogbench::daemon
