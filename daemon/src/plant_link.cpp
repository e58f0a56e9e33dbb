// fogbenchd's link to the plant store (plant_link.hpp).
#include "plant_link.hpp"

#include <fcntl.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <optional>

#include <spdlog/spdlog.h>

#include "fogbench/plant/plant.hpp"
#include "fogbench/storage/outbox.hpp"
#include "fogbench/storage/store.hpp"

namespace fogbench::daemon {

namespace {
double steady_s() { return std::chrono::duration<double>(PlantLink::Clock::now().time_since_epoch()).count(); }
}  // namespace

PlantLink::PlantLink(PlantConfig config, std::filesystem::path store_path)
    : config_(std::move(config)), store_path_(std::move(store_path)) {
  thread_ = std::thread([this] {
    run();
    {
      std::lock_guard lock(mutex_);
      ended_ = true;
      activity_.phase = PlantActivity::Phase::stopped;
    }
    cv_.notify_all();
  });
}

PlantLink::~PlantLink() {
  stop();
  // A thread that would not end (stop() said so) cannot be joined without hanging: the server
  // ends the process instead of destroying the link; this is the last guard.
  if (thread_.joinable()) thread_.detach();
}

void PlantLink::request_stop() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  cv_.notify_all();
}

bool PlantLink::stop() {
  const auto now = Clock::now();
  return stop(now + std::chrono::seconds(3), now + std::chrono::seconds(5));
}

bool PlantLink::stop(Clock::time_point abandon_at, Clock::time_point give_up_at) {
  if (!thread_.joinable()) return true;
  request_stop();
  std::unique_lock lock(mutex_);
  if (!cv_.wait_until(lock, abandon_at, [this] { return ended_; })) {
    const PlantLinkState st = describe(activity_, steady_s(), config_.stall_s);
    if (st.run_id != 0)
      spdlog::warn(
          "plant: stopping: abandoned the transaction sending run {} ({:.1f} s in it, {:.1f} s without progress{}): "
          "nothing of it is committed in the plant; the run stays in the outbox and is sent again at the next start",
          st.run_id, st.busy_s, st.quiet_s, st.stalled ? ", stalled" : "");
    else
      spdlog::warn("plant: stopping: abandoned the link while {} ({:.1f} s)", st.state, st.busy_s);
    abandon();
    if (!cv_.wait_until(lock, give_up_at, [this] { return ended_; })) {
      spdlog::error("plant: the link's thread did not end after its connection was cut ({}); left to the process's end",
                    st.state);
      return false;
    }
  }
  lock.unlock();
  thread_.join();
  return true;
}

void PlantLink::abandon() {
  if (abort_fd_ >= 0) ::shutdown(abort_fd_, SHUT_RDWR);
}

PlantLinkState PlantLink::state() const {
  std::lock_guard lock(mutex_);
  return describe(activity_, steady_s(), config_.stall_s);
}

void PlantLink::set_phase(PlantActivity::Phase phase, std::int64_t run_id) {
  const double now = steady_s();
  std::lock_guard lock(mutex_);
  activity_.phase = phase;
  activity_.run_id = run_id;
  activity_.began_s = now;
  activity_.progress_s = now;
}

bool PlantLink::wait(double seconds) {
  std::unique_lock lock(mutex_);
  cv_.wait_for(lock, std::chrono::duration<double>(seconds), [this] { return stopping_; });
  return !stopping_;
}

void PlantLink::run() {
  // Niced like the analysis worker: on a busy host the loop that acquires wins the CPU. The
  // samples' reader that replicate_run starts inherits it. (SCHED_IDLE was tried: measured with
  // perf, the loop's wake-ups waited no less often behind the reader; docs/performance.md.)
  ::setpriority(PRIO_PROCESS, static_cast<id_t>(::gettid()), 10);
  storage::OpenOptions so;
  so.create = false;
  std::optional<storage::Store> store;
  std::optional<plant::Connection> plant;
  // The connection goes with its abort descriptor: closed first, so an abandon never shuts a
  // descriptor number reused meanwhile.
  auto disconnect = [&] {
    {
      std::lock_guard lock(mutex_);
      if (abort_fd_ >= 0) ::close(abort_fd_);
      abort_fd_ = -1;
    }
    plant.reset();
  };
  struct Disconnect {
    decltype(disconnect)& f;
    ~Disconnect() { f(); }
  } at_end{disconnect};
  double backoff = 1.0;
  bool queued_history = false;
  std::string last_logged;
  auto failed = [&](const std::string& msg) {
    bool stopping = false;
    {
      std::lock_guard lock(mutex_);
      stopping = stopping_;
    }
    if (stopping) {
      spdlog::info("plant: stopping: {}", msg);
      return false;
    }
    if (msg != last_logged) spdlog::warn("plant: {} (retried, the outbox keeps the runs)", msg);
    last_logged = msg;
    const double w = backoff;
    backoff = std::min(backoff * 2, config_.retry_max_s);
    return wait(std::min(w, config_.retry_max_s));
  };
  for (;;) {
    {
      std::lock_guard lock(mutex_);
      if (stopping_) return;
    }
    if (!store) {
      auto s = storage::Store::open(store_path_, so);
      if (!s) {
        if (!failed("open the bench's store: " + s.error().message)) return;
        continue;
      }
      store.emplace(std::move(*s));
    }
    if (!queued_history) {
      // Completed runs never queued (recorded before the plant was configured) go first.
      auto n = store->enqueue_unqueued_completed_runs();
      if (!n) {
        if (!failed(n.error().message)) return;
        continue;
      }
      if (*n > 0) spdlog::info("plant: {} completed runs queued for the plant", *n);
      queued_history = true;
    }
    auto head = store->pending_replications(1);
    if (!head) {
      if (!failed(head.error().message)) return;
      continue;
    }
    if (head->empty()) {
      if (!wait(config_.poll_s)) return;
      continue;
    }
    const storage::OutboxEntry entry = head->front();
    if (!plant) {
      set_phase(PlantActivity::Phase::connecting);
      auto c = plant::Connection::open(config_.conninfo, true, config_.connect_timeout_s);
      set_phase(PlantActivity::Phase::idle);
      if (!c) {
        (void)store->mark_replication_failed(entry.id, c.error().message);
        if (!failed(c.error().message)) return;
        continue;
      }
      plant.emplace(std::move(*c));
      plant->on_progress([this] {
        const double now = steady_s();
        std::lock_guard lock(mutex_);
        activity_.progress_s = now;
      });
      {
        std::lock_guard lock(mutex_);
        abort_fd_ = ::fcntl(plant->socket(), F_DUPFD_CLOEXEC, 0);
        if (stopping_) continue;  // the loop's top ends it
      }
      // Verdicts of runs the plant got before its schema had verdicts (or any it lacks): sent
      // once per connection, nothing when none is missing. A failure is logged and tried again
      // at the next connection; the runs go on meanwhile.
      set_phase(PlantActivity::Phase::sending);
      if (auto n = plant::send_missing_verdicts(*plant, *store, config_.bench_id); !n)
        spdlog::warn("plant: {}", n.error().message);
      else if (*n > 0)
        spdlog::info("plant: sent {} verdict(s) the plant lacked (runs sent before the plant had verdicts)", *n);
      set_phase(PlantActivity::Phase::idle);
      std::lock_guard lock(mutex_);
      if (stopping_) continue;
    }
    set_phase(PlantActivity::Phase::sending, entry.run_id);
    auto r = plant::replicate_run(*plant, *store, config_.bench_id, entry.run_id);
    set_phase(PlantActivity::Phase::idle);
    if (!r) {
      (void)store->mark_replication_failed(entry.id, r.error().message);
      if (r.error().code != plant::PlantErrc::bench_store && r.error().code != plant::PlantErrc::invalid_argument)
        disconnect();  // reconnect: the server may have gone or restarted
      if (!failed(r.error().message)) return;
      continue;
    }
    if (auto ok = store->mark_replicated(entry.id); !ok) {
      // Sent but not marked: it is sent again later, which is harmless (replacement).
      if (!failed("mark the run sent: " + ok.error().message)) return;
      continue;
    }
    backoff = 1.0;
    last_logged.clear();
    spdlog::info(
        "plant: run {} replicated as bench '{}' ({} samples, {} events, {} models, {} verifications, {} identity rows, "
        "{} certificates new, {} already held, {} station keys new)",
        entry.run_id, config_.bench_id, r->samples, r->events, r->models, r->verifications, r->identity_rows,
        r->certificates, r->certificates_held, r->station_keys);
  }
}

}  // namespace fogbench::daemon
