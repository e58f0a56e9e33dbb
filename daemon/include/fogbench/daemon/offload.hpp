// Where fogbenchd runs its long work (fits, verifications, the workbench, large reads): a job
// reads the store through the connection it is given and computes; what it returns then runs on
// the loop thread with the loop's store, the only one that writes. fogbenchd's Offload is a
// worker thread with its own read-only connection to the SQLite file (WAL lets it read beside
// the loop's writes; server.cpp), so the loop keeps answering and acquiring while a fit runs.
// Tests, the golden transcripts and the fuzzer use InlineOffload: the job and its continuation
// run at once, on the caller's store, as if there were no worker.
#pragma once

#include <cstddef>
#include <deque>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <string_view>

namespace fogbench::storage {
class Store;  // store.hpp: a job is handed a connection by reference
}

namespace fogbench::daemon {

// Who asked for a job, which decides when it is served (issue 27, point 6): the station's own
// analyses (a finished run's fit or verification, which plans wait on) first, then the local
// operator's requests (the unix socket), then the network's read-only clients. Within one
// class, in the order submitted.
enum class JobClass { station = 0, local = 1, remote = 2 };

struct JobOrigin {
  JobClass job_class = JobClass::remote;
  std::string address;  // the remote client's address (no port); empty for the others
};

class Offload {
 public:
  using Then = std::function<void()>;                       // runs on the loop thread
  using Job = std::function<Then(storage::Store& reader)>;  // runs on the worker
  virtual ~Offload() = default;
  // Queues the job; it runs after every job of a higher class waiting (JobClass), in the order
  // submitted within its own, one at a time, and its continuation runs on the loop before the
  // next job starts, so a job reads what the jobs before it stored. A job must not throw
  // (catch and turn it into a reply).
  virtual void submit(Job job, JobOrigin origin) = 0;
  // Jobs from `address` waiting or running now (a remote client's share: socket.
  // max_analyses_per_address).
  virtual std::size_t pending_from(std::string_view address) const = 0;
};

// The job and its continuation at once, on one store: no worker.
class InlineOffload final : public Offload {
 public:
  explicit InlineOffload(storage::Store& store) : store_(store) {}
  void submit(Job job, JobOrigin /*origin*/) override {
    if (Then then = job(store_)) then();
  }
  std::size_t pending_from(std::string_view) const override { return 0; }

 private:
  storage::Store& store_;
};

// The order of a worker's waiting jobs (JobClass first, then submission) and the count per
// remote address; no thread of its own, so the order is tested without one.
class JobQueue {
 public:
  void push(Offload::Job job, JobOrigin origin);
  bool empty() const;
  // The next job to run, removed from the queue; its origin's address stays counted until
  // done(address).
  struct Next {
    Offload::Job job;
    std::string address;
  };
  std::optional<Next> pop();
  void done(const std::string& address);
  std::size_t pending_from(std::string_view address) const;

 private:
  struct Waiting {
    Offload::Job job;
    std::string address;
  };
  std::deque<Waiting> classes_[3];                     // by JobClass
  std::map<std::string, std::size_t, std::less<>> by_address_;  // waiting or running, remote only
};

}  // namespace fogbench::daemon
