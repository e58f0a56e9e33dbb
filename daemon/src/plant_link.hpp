// fogbenchd's link to the plant store (issue 14; an internal header of daemon/src/, used by
// server.cpp): a thread of its own, with its own connection to the bench's store, that takes the
// outbox's entries in order and replicates each run to PostgreSQL (fogbench::plant). It never
// touches the loop: acquisition does not wait for the plant, and an outage only grows the outbox.
#pragma once

#include <condition_variable>
#include <filesystem>
#include <mutex>
#include <thread>

#include "fogbench/daemon/config.hpp"

namespace fogbench::daemon {

class PlantLink {
 public:
  PlantLink(PlantConfig config, std::filesystem::path store_path);
  ~PlantLink();
  PlantLink(const PlantLink&) = delete;
  PlantLink& operator=(const PlantLink&) = delete;

  void stop();

 private:
  void run();
  bool wait(double seconds);  // false when stopping

  PlantConfig config_;
  std::filesystem::path store_path_;
  std::mutex mutex_;
  std::condition_variable cv_;
  bool stopping_ = false;
  std::thread thread_;
};

}  // namespace fogbench::daemon
