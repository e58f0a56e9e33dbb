// A resume after a long downtime (issue 27 point 2): how long fogbenchd's event loop is held
// while a 30,000-second gap is stored. A run of 2 units at time scale 50 stores 30 s, fogbenchd
// is killed, the stored seconds' wall times are moved back 600 s (30,000 s of run clock), it is
// started again and the run resumed; a client asks `status` every 2 ms from the resume until the
// gap is stored, and the slowest answer is the loop's longest stall (plus a status's own
// handling, ~0.1 ms; `away_wall_s` 0: the same without a gap, the host's own latencies).
// Usage: bench_daemon_resume_gap [away_wall_s=600]
#include "daemon_bench.hpp"

#include <sqlite3.h>

using namespace fogbench::bench;
using Clock = std::chrono::steady_clock;

int main(int argc, char** argv) {
  const double away_wall_s = argc > 1 ? std::atof(argv[1]) : 600.0;
  const double scale = 50.0;
  LiveBench bench(argv[0], 2, scale, "full");
  std::int64_t run = 0;
  {
    LineClient c(bench.socket());
    if (!c.ok() || !c.line(10s)) LiveBench::fail("connect failed");
    auto start = c.call({{"cmd", "run.start"}, {"profile", "exp1"}, {"units", {"SIM-0001", "SIM-0002"}}});
    if (!start.contains("result")) LiveBench::fail("run.start: " + start.dump());
    run = start["result"]["run_id"].get<std::int64_t>();
    for (int i = 0; i < 300; ++i) {
      auto s = c.call({{"cmd", "status"}});
      if (s["result"]["run"].is_object() && s["result"]["run"]["elapsed_s"].get<double>() >= 30) break;
      std::this_thread::sleep_for(100ms);
    }
  }
  bench.daemon->kill_now();
  sqlite3* db = nullptr;
  if (sqlite3_open((bench.dir / "fogbench.db").c_str(), &db) != SQLITE_OK) LiveBench::fail("open the store");
  const std::string sql = "UPDATE samples SET wall_time = wall_time - " + std::to_string(away_wall_s) +
                          " WHERE run_id = " + std::to_string(run);
  if (sqlite3_exec(db, sql.c_str(), nullptr, nullptr, nullptr) != SQLITE_OK) LiveBench::fail("move the wall times");
  sqlite3_close(db);

  bench.daemon = std::make_unique<Process>(
      std::vector<std::string>{(bench.bin / "fogbenchd").string(), "--config", (bench.dir / "fogbenchd.json").string(),
                               "--time-scale", std::to_string(scale), "--log-level", "warn"},
      bench.dir / "fogbenchd.log");
  if (bench.daemon->read_line(60s).empty()) LiveBench::fail("fogbenchd did not start again");
  LineClient c(bench.socket());
  if (!c.ok() || !c.line(10s)) LiveBench::fail("connect failed");
  for (int i = 0; i < 300; ++i) {
    if (c.call({{"cmd", "status"}})["result"]["chamber"]["link"] == "up") break;
    std::this_thread::sleep_for(100ms);
  }
  const auto t0 = Clock::now();
  auto resumed = c.call({{"cmd", "run.resume"}, {"run_id", run}});
  const double resume_ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  if (!resumed.contains("result")) LiveBench::fail("run.resume: " + resumed.dump());
  std::vector<double> ms;
  double gap_s = 0;
  for (;;) {
    const auto a = Clock::now();
    auto s = c.call({{"cmd", "status"}});
    ms.push_back(std::chrono::duration<double, std::milli>(Clock::now() - a).count());
    const auto& r = s["result"]["run"];
    if (!r.is_object()) LiveBench::fail("the run ended: " + s.dump());
    if (r["state"] != "interrupted" && r["samples_pending"].get<int>() == 0) break;
    if (Clock::now() - t0 > 300s) LiveBench::fail("the gap was not stored in 300 s");
    std::this_thread::sleep_for(2ms);
  }
  const double written_s = std::chrono::duration<double>(Clock::now() - t0).count();
  auto g = c.call({{"cmd", "run.get"}, {"run_id", run}});
  for (const auto& e : g["result"]["events"])
    if (e["kind"] == "fault" && e["detail"].value("resumed", false)) gap_s = e["detail"]["gap_s"].get<double>();
  c.call({{"cmd", "run.abort"}, {"reason", "benchmark done"}});
  std::printf("resume of a %.0f-second gap (2 units, synchronous full): run.resume answered in %.1f ms,\n", gap_s,
              resume_ms);
  std::printf("  gap stored and the run acquiring after %.2f s; %zu status during it: p50 %.2f ms p99 %.2f ms max %.2f ms\n",
              written_s, ms.size(), percentile(ms, 50), percentile(ms, 99), percentile(ms, 100));
  return 0;
}
