// fogbenchd's link to the plant store (plant_link.hpp).
#include "plant_link.hpp"

#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <optional>

#include <spdlog/spdlog.h>

#include "fogbench/plant/plant.hpp"
#include "fogbench/storage/store.hpp"

namespace fogbench::daemon {

PlantLink::PlantLink(PlantConfig config, std::filesystem::path store_path)
    : config_(std::move(config)), store_path_(std::move(store_path)) {
  thread_ = std::thread([this] { run(); });
}

PlantLink::~PlantLink() { stop(); }

void PlantLink::stop() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  cv_.notify_all();
  if (thread_.joinable()) thread_.join();
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
  double backoff = 1.0;
  bool queued_history = false;
  std::string last_logged;
  auto failed = [&](const std::string& msg) {
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
      auto c = plant::Connection::open(config_.conninfo, true);
      if (!c) {
        (void)store->mark_replication_failed(entry.id, c.error().message);
        if (!failed(c.error().message)) return;
        continue;
      }
      plant.emplace(std::move(*c));
    }
    auto r = plant::replicate_run(*plant, *store, config_.bench_id, entry.run_id);
    if (!r) {
      (void)store->mark_replication_failed(entry.id, r.error().message);
      if (r.error().code != plant::PlantErrc::bench_store && r.error().code != plant::PlantErrc::invalid_argument)
        plant.reset();  // reconnect: the server may have gone or restarted
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
