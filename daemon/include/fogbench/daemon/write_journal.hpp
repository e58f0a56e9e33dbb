// The station's writes of state changes and events, kept when the store refuses them for a
// reason that may pass (a full disk, an I/O error, a lock held) and written again later, in
// order, so that a run's audit trail ends up complete once there is room. No clock: the station
// says when to retry. Tested through the station (tests/daemon/station_faults_test.cpp).
#pragma once

#include <cstdint>
#include <deque>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "fogbench/storage/errors.hpp"
#include "fogbench/storage/runs.hpp"

namespace fogbench::storage {
class Store;  // store.hpp: held by reference, used in write_journal.cpp only
}

namespace fogbench::daemon {

class WriteJournal {
 public:
  // A state change (state set) or an event of a run.
  struct Write {
    std::int64_t run_id = 0;
    std::optional<storage::RunState> state;  // a state change; otherwise an event
    std::string reason;
    storage::EventKind kind = storage::EventKind::note;
    std::string detail_json;
    std::optional<double> t_s;
  };

  explicit WriteJournal(storage::Store& store) : store_(store) {}

  // Failures that may pass (room made on the disk, a lock released): worth writing again.
  static bool may_pass(storage::StoreErrc c);

  // Writes now, unless an earlier write of the same run is still kept (then it queues behind
  // it, keeping the order). A refusal that may pass keeps the write; another is logged and lost.
  // Returns true when a write was kept for the first time (the caller starts its retry clock).
  bool write_or_keep(Write w);
  // Writes the kept writes again, oldest first, until the store refuses one that may pass.
  void flush();

  bool empty() const { return kept_.empty(); }
  std::size_t size() const { return kept_.size(); }
  // Whether a write of this run is still kept.
  bool holds(std::int64_t run_id) const;
  // A run's end kept unwritten: {state, reason, recorded: false}; null for any other run.
  nlohmann::json unrecorded_end(std::int64_t run_id) const;

  // Whether the store's last answer was a refusal that may pass: calls then do not wait for
  // another connection's lock (a locked store must not stall the loop at every retry).
  bool refused() const { return refused_; }
  void set_refused(bool r) { refused_ = r; }
  template <class Call>
  auto without_waiting_if_refused(Call&& call) {
    if (!refused_) return call();
    const NoBusyWait no_wait(store_);
    return call();
  }

 private:
  // The store's busy timeout set to 0 for its lifetime, then put back (write_journal.cpp, so
  // that this header needs no more of the store than its name).
  class NoBusyWait {
   public:
    explicit NoBusyWait(storage::Store& store);
    ~NoBusyWait();
    NoBusyWait(const NoBusyWait&) = delete;
    NoBusyWait& operator=(const NoBusyWait&) = delete;

   private:
    storage::Store& store_;
    int wait_ms_;
  };

  storage::StoreResult<void> write(const Write& w);

  storage::Store& store_;
  std::deque<Write> kept_;
  bool refused_ = false;
};

}  // namespace fogbench::daemon
