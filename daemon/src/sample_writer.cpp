// The station's sample writers (sample_writer.hpp): inline on the loop's store, or a thread with
// a write connection of its own.
#include "fogbench/daemon/sample_writer.hpp"

#include <algorithm>
#include <iterator>
#include <utility>

#include <spdlog/spdlog.h>

#include "fogbench/storage/store.hpp"

namespace fogbench::daemon {

namespace {

// Seconds joined into one transaction at most when they queued up behind a slow commit: enough
// to catch up with a disk that took minutes, small enough that one refusal loses little.
constexpr std::size_t kMaxBatchesPerCommit = 600;

// Folds a refusal into the one already kept for the same run, or starts a new one.
void fold(std::deque<SampleWriteFailure>& failures, std::int64_t run_id, double first_t_s, double last_t_s,
          std::int64_t rows, const storage::StoreError& e) {
  for (auto& f : failures) {
    if (f.run_id != run_id) continue;
    f.first_t_s = std::min(f.first_t_s, first_t_s);
    f.last_t_s = std::max(f.last_t_s, last_t_s);
    f.rows += rows;
    return;
  }
  failures.push_back({run_id, first_t_s, last_t_s, rows, e});
}

std::pair<double, double> t_span(const std::vector<storage::SampleRow>& rows) {
  double lo = rows.front().t_s, hi = rows.front().t_s;
  for (const auto& r : rows) {
    lo = std::min(lo, r.t_s);
    hi = std::max(hi, r.t_s);
  }
  return {lo, hi};
}

}  // namespace

std::optional<storage::StoreError> RefusedRuns::find(std::int64_t run_id) const {
  for (const auto& [id, first] : runs_)
    if (id == run_id) return first;
  return std::nullopt;
}

void RefusedRuns::add(std::int64_t run_id, const storage::StoreError& first) {
  if (find(run_id)) return;
  runs_.emplace_back(run_id, first);
  if (runs_.size() > 16) runs_.pop_front();
}

std::vector<storage::SampleRow> gap_rows(const SampleGap& gap, double from_s, double to_s) {
  std::vector<storage::SampleRow> rows;
  if (to_s > from_s) rows.reserve(static_cast<std::size_t>(to_s - from_s) * gap.rows.size());
  for (double t = from_s; t < to_s; t += 1.0)
    for (const auto& r : gap.rows) {
      rows.push_back(r);
      rows.back().t_s = t;
    }
  return rows;
}

// ---------------------------------------------------------------- inline

void InlineSampleWriter::append(std::int64_t run_id, std::vector<storage::SampleRow> rows, double /*clock_s*/) {
  if (rows.empty()) return;
  std::deque<SampleWriteFailure> one;
  if (failure_) one.push_back(*failure_);
  // A hole in the run's seconds is worse than the seconds it would keep (sample_writer.hpp).
  std::optional<storage::StoreError> refusal = refused_.find(run_id);
  if (!refusal)
    if (auto ok = store_.append_samples(run_id, rows); !ok) refusal = ok.error();
  if (!refusal) return;
  refused_.add(run_id, *refusal);
  const auto [lo, hi] = t_span(rows);
  fold(one, run_id, lo, hi, static_cast<std::int64_t>(rows.size()), *refusal);
  failure_ = one.front();
}

void InlineSampleWriter::append_gap(std::int64_t run_id, SampleGap gap, double clock_s) {
  for (double t = gap.from_s; t < gap.to_s; t += kGapSliceSeconds)
    append(run_id, gap_rows(gap, t, std::min(gap.to_s, t + kGapSliceSeconds)), clock_s);
}

std::optional<SampleWriteFailure> InlineSampleWriter::take_failure() {
  auto f = std::move(failure_);
  failure_.reset();
  return f;
}

// ---------------------------------------------------------------- threaded

storage::StoreResult<std::unique_ptr<ThreadedSampleWriter>> ThreadedSampleWriter::open(
    const std::filesystem::path& path, const storage::OpenOptions& options) {
  storage::OpenOptions o = options;
  o.read_only = false;
  o.create = false;
  auto store = storage::Store::open(path, o);
  if (!store) return std::unexpected(store.error());
  return std::unique_ptr<ThreadedSampleWriter>(new ThreadedSampleWriter(std::move(*store)));
}

ThreadedSampleWriter::ThreadedSampleWriter(storage::Store store)
    : store_(std::make_unique<storage::Store>(std::move(store))) {
  thread_ = std::thread([this] { run(); });
}

ThreadedSampleWriter::~ThreadedSampleWriter() { stop(); }

void ThreadedSampleWriter::append(std::int64_t run_id, std::vector<storage::SampleRow> rows, double clock_s) {
  if (rows.empty()) return;
  {
    std::lock_guard lock(mutex_);
    queue_.push_back({run_id, clock_s, std::move(rows), std::nullopt});
    latest_clock_s_ = std::max(latest_clock_s_.value_or(clock_s), clock_s);
  }
  work_.notify_one();
}

void ThreadedSampleWriter::append_gap(std::int64_t run_id, SampleGap gap, double clock_s) {
  if (gap.to_s <= gap.from_s || gap.rows.empty()) return;
  {
    std::lock_guard lock(mutex_);
    queue_.push_back({run_id, clock_s, {}, std::move(gap)});
    latest_clock_s_ = std::max(latest_clock_s_.value_or(clock_s), clock_s);
  }
  work_.notify_one();
}

std::optional<SampleWriteFailure> ThreadedSampleWriter::take_failure() {
  std::lock_guard lock(mutex_);
  if (failures_.empty()) return std::nullopt;
  SampleWriteFailure f = std::move(failures_.front());
  failures_.pop_front();
  return f;
}

bool ThreadedSampleWriter::drain(std::chrono::milliseconds timeout) {
  std::unique_lock lock(mutex_);
  return progress_.wait_for(lock, timeout, [this] { return queue_.empty() && in_flight_ == 0; });
}

std::optional<double> ThreadedSampleWriter::oldest_pending_clock_s() const {
  std::lock_guard lock(mutex_);
  std::optional<double> oldest;
  if (in_flight_clock_s_) oldest = in_flight_clock_s_;
  else if (!queue_.empty()) oldest = queue_.front().clock_s;
  // A gap's slices going in are the store answering: what waits (the rest of the gap, the
  // seconds behind it) is as old as that progress at most.
  if (oldest && gap_progress_clock_s_) oldest = std::max(*oldest, *gap_progress_clock_s_);
  return oldest;
}

std::size_t ThreadedSampleWriter::pending() const {
  std::lock_guard lock(mutex_);
  return queue_.size() + in_flight_;
}

void ThreadedSampleWriter::hold_for_test(bool held) {
  {
    std::lock_guard lock(mutex_);
    held_ = held;
  }
  work_.notify_one();
}

void ThreadedSampleWriter::stop(std::chrono::milliseconds timeout) {
  if (!thread_.joinable()) return;
  const bool drained = drain(timeout);
  std::size_t lost = 0;
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
    held_ = false;
    if (!drained) {
      for (const auto& b : queue_)
        lost += b.gap ? static_cast<std::size_t>(b.gap->to_s - b.gap->from_s) * b.gap->rows.size() : b.rows.size();
      queue_.clear();
    }
  }
  work_.notify_one();
  if (!drained)
    spdlog::error("sample writer: the store did not take the last samples within {} ms; {} queued rows given up",
                  timeout.count(), lost);
  // A commit in progress finishes first (SQLite's own busy timeout bounds it).
  thread_.join();
}

void ThreadedSampleWriter::refuse(std::int64_t run_id, const std::vector<storage::SampleRow>& rows,
                                  const storage::StoreError& e) {
  refused_.add(run_id, e);
  record_failure(run_id, rows, e);
}

void ThreadedSampleWriter::record_failure(std::int64_t run_id, const std::vector<storage::SampleRow>& rows,
                                          const storage::StoreError& e) {
  const auto [lo, hi] = t_span(rows);
  spdlog::error("sample writer: {} rows of run {} (t_s {} to {} s) not stored ({}): {}", rows.size(), run_id, lo, hi,
                storage::to_string(e.code), e.message);
  fold(failures_, run_id, lo, hi, static_cast<std::int64_t>(rows.size()), e);
}

void ThreadedSampleWriter::run() {
  std::unique_lock lock(mutex_);
  for (;;) {
    work_.wait(lock, [this] { return stopping_ || (!held_ && !queue_.empty()); });
    if (queue_.empty()) return;  // stopping, nothing left
    const std::int64_t run_id = queue_.front().run_id;
    in_flight_clock_s_ = queue_.front().clock_s;
    if (queue_.front().gap) {
      // A resume's gap: one slice a transaction; the rest stays first in the queue, so the
      // seconds handed over after it are stored after it.
      SampleGap& gap = *queue_.front().gap;
      if (auto first = refused_.find(run_id)) {
        // The run's samples were refused: none of its gap is written either (no hole).
        const auto n = static_cast<std::int64_t>(gap.to_s - gap.from_s) * static_cast<std::int64_t>(gap.rows.size());
        spdlog::error("sample writer: the gap of run {} (t_s {} to {} s, {} rows) not stored: the run's samples were refused",
                      run_id, gap.from_s, gap.to_s - 1.0, n);
        fold(failures_, run_id, gap.from_s, gap.to_s - 1.0, n, *first);
        queue_.pop_front();
        in_flight_clock_s_.reset();
        progress_.notify_all();
        continue;
      }
      const double from_s = gap.from_s, to_s = std::min(gap.to_s, from_s + kGapSliceSeconds);
      std::vector<storage::SampleRow> rows = gap_rows(gap, from_s, to_s);
      gap.from_s = to_s;
      if (to_s >= gap.to_s) queue_.pop_front();
      in_flight_ = 1;
      const bool more = to_s < gap.to_s;
      lock.unlock();
      const auto began = std::chrono::steady_clock::now();
      auto ok = store_->append_samples(run_id, rows);
      const auto took = std::chrono::steady_clock::now() - began;
      lock.lock();
      if (!ok) refuse(run_id, rows, ok.error());
      else gap_progress_clock_s_ = latest_clock_s_;
      in_flight_ = 0;
      in_flight_clock_s_.reset();
      progress_.notify_all();
      // Slices back to back would keep the write lock from the loop's own connection (its
      // busy handler retries in sleeps that land in the next slice): the loop's event or state
      // change would wait for the whole gap. A pause as long as the slice took lets it in.
      if (more) {
        lock.unlock();
        std::this_thread::sleep_for(std::max<std::chrono::steady_clock::duration>(took, std::chrono::milliseconds(2)));
        lock.lock();
      }
      continue;
    }
    // The seconds of one run that queued up go into one transaction (one fsync).
    std::vector<storage::SampleRow> rows = std::move(queue_.front().rows);
    queue_.pop_front();
    in_flight_ = 1;
    while (!queue_.empty() && !queue_.front().gap && queue_.front().run_id == run_id &&
           in_flight_ < kMaxBatchesPerCommit) {
      auto& next = queue_.front().rows;
      rows.insert(rows.end(), std::make_move_iterator(next.begin()), std::make_move_iterator(next.end()));
      queue_.pop_front();
      ++in_flight_;
    }
    if (auto first = refused_.find(run_id)) {
      // A hole in the run's seconds is worse than the seconds it would keep (sample_writer.hpp).
      record_failure(run_id, rows, *first);
    } else {
      lock.unlock();
      auto ok = store_->append_samples(run_id, rows);
      lock.lock();
      if (!ok) refuse(run_id, rows, ok.error());
    }
    in_flight_ = 0;
    in_flight_clock_s_.reset();
    progress_.notify_all();
  }
}

}  // namespace fogbench::daemon
