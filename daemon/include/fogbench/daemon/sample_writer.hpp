// Where the station's once-a-second samples are committed. fogbenchd's writer is a thread with
// its own write connection to the store (ThreadedSampleWriter): the loop hands it a second's rows
// and goes on, so the commit's fsync (synchronous=FULL), a checkpoint, or another connection's
// write lock (the plant link's outbox, fogctl) never holds the loop that acquires (issue 14: the
// acquisition unaffected while the bench replicates; docs/daemon.md "Threads"). Tests of the
// station, the golden transcripts and an in-memory store use InlineSampleWriter: the rows are
// committed at once on the station's store, as if there were no thread.
//
// What the station relies on, both ways: rows are committed in the order handed over, each
// hand-over all or nothing (the writer may join several of one run into one transaction: then
// all or nothing together); a refused commit is reported by take_failure(), never lost silently;
// after a refusal, the run's later hand-overs are refused with it, untried, so a run's stored
// seconds are always a gapless prefix (a disk full for one batch may take the next after a
// checkpoint freed pages: the hole that would leave is worse than the seconds it would keep);
// drain() returns once everything handed over is committed or reported (the run's end is
// recorded after its samples, and its analysis reads them all).
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <expected>
#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>
#include <utility>
#include <vector>

#include "fogbench/storage/errors.hpp"
#include "fogbench/storage/samples.hpp"

namespace fogbench::storage {
class Store;  // store.hpp: the writers use it in sample_writer.cpp only
struct OpenOptions;
}  // namespace fogbench::storage

namespace fogbench::daemon {

// Rows the store refused: the run, the seconds lost and why (the first refusal's error).
struct SampleWriteFailure {
  std::int64_t run_id = 0;
  double first_t_s = 0.0;     // the earliest second lost, s since the run's start
  double last_t_s = 0.0;      // the latest second lost, s
  std::int64_t rows = 0;      // sample rows lost (all units)
  storage::StoreError error;  // the first refusal
};

// The runs whose samples were refused (the latest few; a run ends at its first refusal, so the
// list only needs to outlive the batches already queued behind it).
class RefusedRuns {
 public:
  // The run's first refusal, when it had one.
  std::optional<storage::StoreError> find(std::int64_t run_id) const;
  void add(std::int64_t run_id, const storage::StoreError& first);

 private:
  std::deque<std::pair<std::int64_t, storage::StoreError>> runs_;
};

// The seconds a resumed run was away (Station::resume_run): [from_s, to_s) of the run clock, each
// stored as `rows` (one per unit, flagged missing + link_gap; their t_s is set per second). A gap
// of a long downtime is tens of thousands of seconds: it is written in slices of
// kGapSliceSeconds, one transaction each, with a pause as long as each took after it (the loop's
// connection gets the write lock between them), so a kill loses at most the slice in progress and the
// seconds written stay (the next resume completes the gap from the last stored second).
struct SampleGap {
  double from_s = 0.0;  // the first second of the gap, s since the run's start
  double to_s = 0.0;    // one past the last, s
  std::vector<storage::SampleRow> rows;
};
inline constexpr double kGapSliceSeconds = 120.0;
// The rows of the gap's seconds [from_s, to_s), every unit's for each second.
std::vector<storage::SampleRow> gap_rows(const SampleGap& gap, double from_s, double to_s);

class SampleWriter {
 public:
  virtual ~SampleWriter() = default;
  // Hands over one second's rows of a run (every unit), tagged with the daemon's clock at the
  // hand-over (s), which oldest_pending_clock_s() gives back. Inline: committed before it returns.
  virtual void append(std::int64_t run_id, std::vector<storage::SampleRow> rows, double clock_s) = 0;
  // Hands over a resumed run's gap (SampleGap), to be stored before anything handed over after
  // it, slice by slice. The thread writes it off the loop; it counts as one hand-over, tagged
  // `clock_s`, until its last slice is committed. Inline: written before it returns.
  virtual void append_gap(std::int64_t run_id, SampleGap gap, double clock_s) = 0;
  // The refusals not yet taken, folded into one per run (the first run's when several).
  virtual std::optional<SampleWriteFailure> take_failure() = 0;
  // Waits until every row handed over is committed or refused, `timeout` at most. False: rows
  // are still waiting (a stalled disk), and they stay queued.
  virtual bool drain(std::chrono::milliseconds timeout) = 0;
  // The tag of the oldest hand-over not yet committed or refused; empty when none waits. While a
  // resume's gap is written, and after it, its progress counts: once a slice of it is committed
  // the answer is no older than the latest tag handed over by then (a gap of any length, and the
  // seconds queued behind it, are not "stalled" while its slices go in; issue 27: a gap over
  // some 800,000 s of 2 units took more than the 30 s stall rule and aborted the run).
  virtual std::optional<double> oldest_pending_clock_s() const = 0;
  // Hand-overs (seconds) not yet committed or refused.
  virtual std::size_t pending() const = 0;
};

// Commits on the caller's store, at once.
class InlineSampleWriter final : public SampleWriter {
 public:
  explicit InlineSampleWriter(storage::Store& store) : store_(store) {}
  void append(std::int64_t run_id, std::vector<storage::SampleRow> rows, double clock_s) override;
  void append_gap(std::int64_t run_id, SampleGap gap, double clock_s) override;
  std::optional<SampleWriteFailure> take_failure() override;
  bool drain(std::chrono::milliseconds) override { return true; }
  std::optional<double> oldest_pending_clock_s() const override { return std::nullopt; }
  std::size_t pending() const override { return 0; }

 private:
  storage::Store& store_;
  std::optional<SampleWriteFailure> failure_;
  RefusedRuns refused_;
};

// A thread of its own with a write connection of its own (SQLite's WAL lets two connections of
// one process take turns at the write lock; each waits OpenOptions::busy_timeout_ms for the
// other). Runs at the loop's priority, not niced: it is part of the acquisition. Seconds that
// queued up behind a slow commit go into the next transaction together (one fsync for them all),
// so a slow disk is caught up with rather than fallen behind.
class ThreadedSampleWriter final : public SampleWriter {
 public:
  // Opens the connection (the store must exist: the loop's connection made and migrated it) and
  // starts the thread.
  static storage::StoreResult<std::unique_ptr<ThreadedSampleWriter>> open(const std::filesystem::path& path,
                                                                           const storage::OpenOptions& options);
  ~ThreadedSampleWriter() override;
  ThreadedSampleWriter(const ThreadedSampleWriter&) = delete;
  ThreadedSampleWriter& operator=(const ThreadedSampleWriter&) = delete;

  void append(std::int64_t run_id, std::vector<storage::SampleRow> rows, double clock_s) override;
  void append_gap(std::int64_t run_id, SampleGap gap, double clock_s) override;
  std::optional<SampleWriteFailure> take_failure() override;
  bool drain(std::chrono::milliseconds timeout) override;
  std::optional<double> oldest_pending_clock_s() const override;
  std::size_t pending() const override;

  // Commits what was handed over (`timeout` at most), then ends the thread. Rows still queued
  // after the timeout are lost and logged. Idempotent; the destructor calls it.
  void stop(std::chrono::milliseconds timeout = std::chrono::seconds(10));

  // Tests: while held, the thread takes no new batch (as a disk that does not answer would
  // keep it), so the queue, pending() and the station's stall rule can be seen deterministically.
  void hold_for_test(bool held);

 private:
  explicit ThreadedSampleWriter(storage::Store store);
  struct Batch {
    std::int64_t run_id = 0;
    double clock_s = 0.0;
    std::vector<storage::SampleRow> rows;
    std::optional<SampleGap> gap;  // a gap's seconds not yet written (rows empty); stays first until done
  };
  void run();
  void record_failure(std::int64_t run_id, const std::vector<storage::SampleRow>& rows, const storage::StoreError& e);
  // A refusal by the store: the run is refused from now on (RefusedRuns), and the rows recorded.
  void refuse(std::int64_t run_id, const std::vector<storage::SampleRow>& rows, const storage::StoreError& e);

  std::unique_ptr<storage::Store> store_;  // the thread's own connection (a pointer: see the includes)
  mutable std::mutex mutex_;
  std::condition_variable work_;      // a batch queued, stop asked, hold released
  std::condition_variable progress_;  // a batch committed or refused
  std::deque<Batch> queue_;
  std::optional<double> in_flight_clock_s_;  // the oldest tag of the transaction being written
  std::optional<double> latest_clock_s_;     // the latest tag handed over
  std::optional<double> gap_progress_clock_s_;  // latest_clock_s_ when a gap's slice was last committed
  std::size_t in_flight_ = 0;                // its hand-overs
  std::deque<SampleWriteFailure> failures_;
  RefusedRuns refused_;
  bool stopping_ = false;
  bool held_ = false;
  std::thread thread_;
};

}  // namespace fogbench::daemon
