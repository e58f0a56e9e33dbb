// Where fogbenchd runs its long work (fits, verifications, the workbench, large reads): a job
// reads the store through the connection it is given and computes; what it returns then runs on
// the loop thread with the loop's store, the only one that writes. fogbenchd's Offload is a
// worker thread with its own read-only connection to the SQLite file (WAL lets it read beside
// the loop's writes; server.cpp), so the loop keeps answering and acquiring while a fit runs.
// Tests, the golden transcripts and the fuzzer use InlineOffload: the job and its continuation
// run at once, on the caller's store, as if there were no worker.
#pragma once

#include <functional>

#include "fogbench/storage/store.hpp"

namespace fogbench::daemon {

class Offload {
 public:
  using Then = std::function<void()>;                    // runs on the loop thread
  using Job = std::function<Then(storage::Store& reader)>;  // runs on the worker
  virtual ~Offload() = default;
  // Queues the job; jobs run one at a time in the order submitted, and their continuations run
  // on the loop in that order too. A job must not throw (catch and turn it into a reply).
  virtual void submit(Job job) = 0;
};

// The job and its continuation at once, on one store: no worker.
class InlineOffload final : public Offload {
 public:
  explicit InlineOffload(storage::Store& store) : store_(store) {}
  void submit(Job job) override {
    if (Then then = job(store_)) then();
  }

 private:
  storage::Store& store_;
};

}  // namespace fogbench::daemon
