// bench_plant_replicate: the replication rate into a local PostgreSQL (issue 14: at least
// 200,000 sample rows per second by COPY). A bench store with one completed run of 2 units x
// N s is made in a temporary file, then replicated (plant::replicate_run: one transaction,
// COPY) several times as different benches; the rate counts sample rows over the whole call.
// --prefill ROWS first sends the run as filler benches until the plant's samples table holds at
// least ROWS rows (the target is for a plant holding millions, whose primary key's index is large).
//   bench_plant_replicate --db CONNSTR [--seconds 250000] [--repeat 3] [--prefill 0]
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>

#include "fogbench/plant/plant.hpp"
#include "fogbench/storage/runs.hpp"
#include "fogbench/storage/samples.hpp"
#include "fogbench/storage/store.hpp"

using namespace fogbench;
using Clock = std::chrono::steady_clock;

int main(int argc, char** argv) {
  std::string db;
  int seconds = 250000, repeat = 3;
  long long prefill = 0;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--db" && i + 1 < argc) db = argv[++i];
    else if (a == "--seconds" && i + 1 < argc) seconds = std::stoi(argv[++i]);
    else if (a == "--repeat" && i + 1 < argc) repeat = std::stoi(argv[++i]);
    else if (a == "--prefill" && i + 1 < argc) prefill = std::stoll(argv[++i]);
    else
      return std::fprintf(stderr,
                          "usage: bench_plant_replicate --db CONNSTR [--seconds N] [--repeat N] [--prefill ROWS]\n"),
             2;
  }
  if (db.empty()) return std::fprintf(stderr, "bench_plant_replicate: --db is required\n"), 2;
  const auto path = std::filesystem::temp_directory_path() / ("fogbench-bench-replicate-" + std::to_string(::getpid()) + ".db");
  storage::OpenOptions so;
  so.synchronous_full = false;
  auto store = storage::Store::open(path, so);
  if (!store) return std::fprintf(stderr, "%s\n", store.error().message.c_str()), 1;
  storage::NewRun nr;
  nr.profile_name = "bench";
  nr.unit_serials = {"FOG-1", "FOG-2"};
  nr.unit_lots = {std::string("L-1"), std::string("L-2")};
  auto id = store->create_run(nr);
  (void)store->set_run_state(*id, storage::RunState::running, "bench");
  std::vector<storage::SampleRow> rows;
  for (int s = 0; s < seconds; ++s) {
    for (int u = 0; u < 2; ++u) {
      storage::SampleRow r;
      r.unit_index = u;
      r.t_s = s;
      r.wall_time = 1.7e9 + s;
      r.setpoint_c = 20 + 20 * std::sin(s / 3000.0);
      r.chamber_c = r.setpoint_c + 0.1;
      r.gyro_dph = 0.5 + 0.01 * r.chamber_c;
      r.frames = 100;
      r.t1_c = r.chamber_c - 0.3;
      r.t2_c = r.chamber_c - 0.2;
      r.phase = model::Phase::hold;
      r.step = 1;
      r.since_power_on_s = s + 10;
      rows.push_back(r);
    }
    if (rows.size() >= 20000) {
      if (auto ok = store->append_samples(*id, rows); !ok) return std::fprintf(stderr, "%s\n", ok.error().message.c_str()), 1;
      rows.clear();
    }
  }
  if (!rows.empty()) (void)store->append_samples(*id, rows);
  (void)store->set_run_state(*id, storage::RunState::completed, "bench");
  auto c = plant::Connection::open(db, true);
  if (!c) return std::fprintf(stderr, "%s\n", c.error().message.c_str()), 1;
  auto held = [&]() -> long long {
    auto r = c->query("SELECT count(*) FROM fogbench.samples", {}, "count the plant's samples");
    return r && !r->rows.empty() ? std::stoll(r->rows[0][0].value_or("0")) : -1;
  };
  for (int k = 0; held() < prefill; ++k) {
    const std::string filler = "bench-prefill-" + std::to_string(::getpid()) + "-" + std::to_string(k);
    if (auto r = plant::replicate_run(*c, *store, filler, *id); !r)
      return std::fprintf(stderr, "%s\n", r.error().message.c_str()), 1;
  }
  const long long before = held();
  double best = 1e9;
  std::int64_t n = 0;
  plant::ReplicateStats last;
  for (int k = 0; k < repeat; ++k) {
    const auto t0 = Clock::now();
    // A new bench id each time: a first sending, the normal case (a re-send also deletes).
    const std::string bench = "bench-replicate-" + std::to_string(::getpid()) + "-" + std::to_string(k);
    auto r = plant::replicate_run(*c, *store, bench, *id);
    if (!r) return std::fprintf(stderr, "%s\n", r.error().message.c_str()), 1;
    best = std::min(best, std::chrono::duration<double>(Clock::now() - t0).count());
    n = r->samples;
    last = *r;
  }
  std::printf("replicated %lld sample rows in %.2f s (best of %d first sendings into a plant holding %lld "
              "sample rows): %.0f rows/s\n",
              static_cast<long long>(n), best, repeat, before, static_cast<double>(n) / best);
  std::printf("each sending: %lld units, %lld samples, %lld events, %lld models, %lld verifications, %lld figures, "
              "%lld identity rows, %lld certificates new, %lld already held\n",
              static_cast<long long>(last.units), static_cast<long long>(last.samples),
              static_cast<long long>(last.events), static_cast<long long>(last.models),
              static_cast<long long>(last.verifications), static_cast<long long>(last.figures),
              static_cast<long long>(last.identity_rows), static_cast<long long>(last.certificates),
              static_cast<long long>(last.certificates_held));
  std::filesystem::remove(path);
  std::filesystem::remove(path.string() + "-wal");
  std::filesystem::remove(path.string() + "-shm");
  return 0;
}
