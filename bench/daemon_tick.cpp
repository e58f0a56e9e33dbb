// fogbenchd's one-second tick at real time: how far each stored sample's wall time is from the
// absolute schedule t0 + k seconds (jitter), and whether the schedule drifts. The run acquires
// 2 units of the mock bench at time scale 1. Usage: bench_daemon_tick [seconds=60]
#include "daemon_bench.hpp"

using namespace fogbench::bench;

int main(int argc, char** argv) {
  const int seconds = argc > 1 ? std::atoi(argv[1]) : 60;
  LiveBench bench(argv[0], 2, 1.0);
  LineClient c(bench.socket());
  if (!c.ok() || !c.line(10s)) LiveBench::fail("connect failed");
  auto start = c.call({{"cmd", "run.start"}, {"profile", "exp1"}, {"units", {"SIM-0001", "SIM-0002"}}});
  if (!start.contains("result")) LiveBench::fail("run.start: " + start.dump());
  const auto run = start["result"]["run_id"].get<std::int64_t>();
  std::this_thread::sleep_for(std::chrono::seconds(seconds + 1));
  auto page = c.call({{"cmd", "run.samples"}, {"run_id", run}, {"unit", 0}, {"limit", 10000}});
  c.call({{"cmd", "run.abort"}, {"reason", "benchmark done"}});
  const auto& rows = page["result"]["samples"];
  if (rows.size() < 10) LiveBench::fail("too few samples");
  // wall_time is stamped at the start of each tick's handling; the schedule is t0 + t_s.
  std::vector<double> offset_ms;
  const double w0 = rows[0]["wall_time"].get<double>(), s0 = rows[0]["t_s"].get<double>();
  for (const auto& r : rows)
    offset_ms.push_back((r["wall_time"].get<double>() - w0 - (r["t_s"].get<double>() - s0)) * 1e3);
  const double median = percentile(offset_ms, 50);
  std::vector<double> jitter;
  for (double o : offset_ms) jitter.push_back(std::abs(o - median));
  std::printf("tick at time scale 1, %zu ticks (%d s), |wall time - schedule| about its median:\n", rows.size(), seconds);
  std::printf("  p50 %.3f ms  p99 %.3f ms  max %.3f ms; drift first->last tick %.3f ms\n", percentile(jitter, 50),
              percentile(jitter, 99), percentile(jitter, 100), offset_ms.back() - offset_ms.front());
  return 0;
}
