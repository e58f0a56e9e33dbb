// bench_plant_tick: the acquisition while fogbenchd replicates to the plant (issue 14: "the bench's
// acquisition unaffected while it replicates, tick jitter p99 unchanged within noise").
//
// The real fogbench-sim and fogbenchd at time scale 1 acquire 2 units of exp1 for N s, as
// bench_daemon_tick does, on a store that already holds one completed run of 2 units x ROWS/2 s.
// Twice per round: without a `plant` section, then with one pointing at --db, while this
// process keeps the daemon's outbox fed (the stored run queued again each time the outbox
// empties: replication, delete and COPY, runs for the whole window). Reported per sitting: the
// tick's |wall time - schedule| about its median (p50, p99, max) and how many sample rows the
// daemon's link replicated during the window.
// --synchronous normal: the daemon's store without an fsync per commit (default full, as
// bench_daemon_tick).
//   bench_plant_tick --db CONNSTR [--seconds 60] [--rows 400000] [--rounds 1] [--synchronous full]
#include <unistd.h>

#include <atomic>
#include <thread>

#include "daemon_bench.hpp"
#include "fogbench/storage/outbox.hpp"
#include "fogbench/storage/runs.hpp"
#include "fogbench/storage/samples.hpp"
#include "fogbench/storage/store.hpp"

using namespace fogbench;
using namespace fogbench::bench;

namespace {

struct Sitting {
  double p50_ms = 0, p99_ms = 0, max_ms = 0;
  std::size_t ticks = 0;
  std::size_t over_0_5_ms = 0, over_1_ms = 0;  // ticks whose jitter exceeds 0.5 ms, 1 ms
  std::int64_t replications = 0, rows_replicated = 0;
};

std::int64_t make_stored_run(const std::filesystem::path& db, int rows) {
  storage::OpenOptions so;
  so.synchronous_full = false;
  auto store = storage::Store::open(db, so);
  if (!store) LiveBench::fail(store.error().message);
  storage::NewRun nr;
  nr.profile_name = "stored";
  nr.unit_serials = {"FOG-1", "FOG-2"};
  auto id = store->create_run(nr);
  if (!id) LiveBench::fail(id.error().message);
  (void)store->set_run_state(*id, storage::RunState::running, "bench");
  std::vector<storage::SampleRow> page;
  for (int s = 0; s < rows / 2; ++s) {
    for (int u = 0; u < 2; ++u) {
      storage::SampleRow r;
      r.unit_index = u;
      r.t_s = s;
      r.wall_time = 1.7e9 + s;
      r.setpoint_c = 20;
      r.chamber_c = 20.1;
      r.gyro_dph = 0.5 + 1e-6 * s;
      r.frames = 100;
      r.t1_c = 19.8;
      r.t2_c = 19.9;
      r.phase = model::Phase::hold;
      r.step = 1;
      page.push_back(r);
    }
    if (page.size() >= 20000) {
      if (auto ok = store->append_samples(*id, page); !ok) LiveBench::fail(ok.error().message);
      page.clear();
    }
  }
  if (!page.empty()) (void)store->append_samples(*id, page);
  (void)store->set_run_state(*id, storage::RunState::completed, "bench");
  return *id;
}

Sitting sit(const char* argv0, const std::string& db, int seconds, int rows, bool replicate, int k,
           const std::string& synchronous) {
  std::int64_t stored = 0;
  const std::string bench_id = "tick-" + std::to_string(::getpid()) + "-" + std::to_string(k);
  LiveBench bench(argv0, 2, 1.0, synchronous, [&](const std::filesystem::path& dir) {
    stored = make_stored_run(dir / "fogbench.db", rows);
    if (!replicate) return;
    json c;
    std::ifstream(dir / "fogbenchd.json") >> c;
    c["plant"] = {{"conninfo", db}, {"bench_id", bench_id}, {"poll_s", 0.05}, {"retry_max_s", 1}};
    std::ofstream(dir / "fogbenchd.json") << c.dump(2);
  });
  LineClient c(bench.socket());
  if (!c.ok() || !c.line(10s)) LiveBench::fail("connect failed");
  auto start = c.call({{"cmd", "run.start"}, {"profile", "exp1"}, {"units", {"SIM-0001", "SIM-0002"}}});
  if (!start.contains("result")) LiveBench::fail("run.start: " + start.dump());
  const auto run = start["result"]["run_id"].get<std::int64_t>();

  // The feeder: the stored run queued again whenever the outbox is empty.
  Sitting out;
  std::atomic<bool> stop{false};
  std::int64_t sent_before = 0, sent_after = 0;
  std::thread feeder;
  if (replicate) {
    feeder = std::thread([&] {
      auto store = storage::Store::open(bench.dir / "fogbench.db");
      if (!store) LiveBench::fail(store.error().message);
      sent_before = store->outbox_status()->sent;
      while (!stop) {
        auto st = store->outbox_status();
        if (st && st->depth == 0) (void)store->enqueue_replication(stored);
        std::this_thread::sleep_for(50ms);
      }
      sent_after = store->outbox_status()->sent;
    });
  }
  std::this_thread::sleep_for(std::chrono::seconds(seconds + 1));
  stop = true;
  if (feeder.joinable()) feeder.join();
  auto page = c.call({{"cmd", "run.samples"}, {"run_id", run}, {"unit", 0}, {"limit", 10000}});
  c.call({{"cmd", "run.abort"}, {"reason", "benchmark done"}});
  const auto& samples = page["result"]["samples"];
  if (samples.size() < 10) LiveBench::fail("too few samples: " + page.dump().substr(0, 300));
  std::vector<double> offset_ms;
  const double w0 = samples[0]["wall_time"].get<double>(), s0 = samples[0]["t_s"].get<double>();
  for (const auto& r : samples)
    offset_ms.push_back((r["wall_time"].get<double>() - w0 - (r["t_s"].get<double>() - s0)) * 1e3);
  const double median = percentile(offset_ms, 50);
  std::vector<double> jitter;
  for (double o : offset_ms) jitter.push_back(std::abs(o - median));
  out.ticks = samples.size();
  out.p50_ms = percentile(jitter, 50);
  out.p99_ms = percentile(jitter, 99);
  out.max_ms = percentile(jitter, 100);
  for (double j : jitter) {
    out.over_0_5_ms += j > 0.5;
    out.over_1_ms += j > 1.0;
  }
  out.replications = sent_after - sent_before;
  out.rows_replicated = out.replications * rows;
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  std::string db;
  int seconds = 60, rows = 400000, rounds = 1;
  std::string synchronous = "full";
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--db" && i + 1 < argc) db = argv[++i];
    else if (a == "--seconds" && i + 1 < argc) seconds = std::stoi(argv[++i]);
    else if (a == "--rows" && i + 1 < argc) rows = std::stoi(argv[++i]);
    else if (a == "--rounds" && i + 1 < argc) rounds = std::stoi(argv[++i]);
    else if (a == "--synchronous" && i + 1 < argc) synchronous = argv[++i];
    else
      return std::fprintf(stderr,
                          "usage: bench_plant_tick --db CONNSTR [--seconds 60] [--rows 400000] [--rounds 1] "
                          "[--synchronous full|normal]\n"),
             2;
  }
  if (db.empty()) return std::fprintf(stderr, "bench_plant_tick: --db is required\n"), 2;
  std::printf("tick at time scale 1, 2 units, %d s per sitting, synchronous=%s; a stored run of %d sample rows "
              "replicated over and over during the sittings 'with':\n",
              seconds, synchronous.c_str(), rows);
  for (int k = 0; k < rounds; ++k) {
    for (bool replicate : {false, true}) {
      const Sitting s = sit(argv[0], db, seconds, rows, replicate, k, synchronous);
      std::printf("  %-7s %zu ticks: p50 %.3f ms  p99 %.3f ms  max %.3f ms  (%zu over 0.5 ms, %zu over 1 ms)",
                  replicate ? "with" : "without", s.ticks, s.p50_ms, s.p99_ms, s.max_ms, s.over_0_5_ms, s.over_1_ms);
      if (replicate)
        std::printf("; %lld replications, %.0f rows/s replicated", static_cast<long long>(s.replications),
                    static_cast<double>(s.rows_replicated) / seconds);
      std::printf("\n");
      std::fflush(stdout);
    }
  }
  return 0;
}
