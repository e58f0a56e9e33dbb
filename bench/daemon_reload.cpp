// The configuration's reload with a run acquiring (issue 24: under 100 ms, no second lost). A
// run of one unit at time scale 20 acquires on the mock bench; `rounds` times the file is
// rewritten (slot B's default serial and socket.max_clients changed, socket.path too: a key that
// needs a restart) and reloaded, alternately by `config.reload` (the reply's round trip) and by
// SIGHUP (from the signal until `status` shows the new default serial, polled every 0.5 ms: an
// upper bound). At the end the run is aborted and its stored seconds compared with its run time.
// Usage: bench_daemon_reload [rounds=40]
#include "daemon_bench.hpp"

#include <signal.h>

#include <chrono>
#include <thread>

#include "fogbench/storage/store.hpp"

using namespace fogbench::bench;
using Clock = std::chrono::steady_clock;

int main(int argc, char** argv) {
  const int rounds = argc > 1 ? std::max(2, std::atoi(argv[1])) : 40;
  const double scale = 20.0;
  LiveBench bench(argv[0], 2, scale, "full");
  LineClient c(bench.socket());
  if (!c.ok() || !c.line(10s)) LiveBench::fail("connect failed");
  for (int i = 0; i < 300; ++i) {
    if (c.call({{"cmd", "status"}})["result"]["chamber"]["link"] == "up") break;
    std::this_thread::sleep_for(100ms);
  }
  auto start = c.call({{"cmd", "run.start"}, {"profile", "exp1"}, {"units", {"SIM-0001"}}});
  if (!start.contains("result")) LiveBench::fail("run.start: " + start.dump());
  const auto run = start["result"]["run_id"].get<std::int64_t>();
  for (int i = 0; i < 300; ++i) {
    auto s = c.call({{"cmd", "status"}});
    if (s["result"]["run"].is_object() && s["result"]["run"]["elapsed_s"].get<double>() >= 10) break;
    std::this_thread::sleep_for(100ms);
  }

  std::ifstream in(bench.dir / "fogbenchd.json");
  const json original = json::parse(in);
  std::vector<double> command_ms, signal_ms, daemon_ms;
  for (int k = 0; k < rounds; ++k) {
    json cfg = original;
    const std::string serial = "FOG-" + std::to_string(1000 + k);
    cfg["drivers"]["units"][1]["serial"] = serial;
    cfg["socket"]["max_clients"] = 100 + k;
    cfg["socket"]["path"] = "elsewhere.sock";
    std::ofstream(bench.dir / "fogbenchd.json") << cfg.dump(2);
    if (k % 2 == 0) {
      const auto t0 = Clock::now();
      auto r = c.call({{"cmd", "config.reload"}});
      command_ms.push_back(std::chrono::duration<double, std::milli>(Clock::now() - t0).count());
      if (!r.contains("result")) LiveBench::fail("config.reload: " + r.dump());
      daemon_ms.push_back(r["result"]["elapsed_ms"].get<double>());
    } else {
      const auto t0 = Clock::now();
      ::kill(bench.daemon->pid(), SIGHUP);
      for (;;) {
        auto s = c.call({{"cmd", "status"}});
        if (s["result"]["units"][1]["serial"] == serial) break;
        if (Clock::now() - t0 > 10s) LiveBench::fail("SIGHUP: the new serial not seen in 10 s");
        std::this_thread::sleep_for(500us);
      }
      signal_ms.push_back(std::chrono::duration<double, std::milli>(Clock::now() - t0).count());
    }
    std::this_thread::sleep_for(50ms);
  }
  std::ofstream(bench.dir / "fogbenchd.json") << original.dump(2);

  c.call({{"cmd", "run.abort"}, {"reason", "benchmark done"}});
  json last;
  for (int i = 0; i < 300; ++i) {
    last = c.call({{"cmd", "status"}})["result"]["last_run"];
    if (last.is_object() && last["run_id"] == run) break;
    std::this_thread::sleep_for(100ms);
  }
  fogbench::storage::OpenOptions ro;
  ro.read_only = true;
  auto store = fogbench::storage::Store::open(bench.dir / "fogbench.db", ro);
  if (!store) LiveBench::fail("open the store");
  auto n = store->count_samples(run, 0);
  if (!n) LiveBench::fail("count the samples");
  const double elapsed = last["elapsed_s"].get<double>();
  std::printf("configuration reload with a run acquiring (1 unit, time scale %.0f, %d reloads):\n", scale, rounds);
  std::printf("  config.reload round trip: p50 %.2f ms  max %.2f ms (the daemon's own part: p50 %.2f ms max %.2f ms)\n",
              percentile(command_ms, 50), percentile(command_ms, 100), percentile(daemon_ms, 50), percentile(daemon_ms, 100));
  std::printf("  SIGHUP to status showing the new serial: p50 %.2f ms  max %.2f ms\n", percentile(signal_ms, 50),
              percentile(signal_ms, 100));
  std::printf("  run %lld: %lld seconds stored over %.0f s of run time (%s)\n", static_cast<long long>(run),
              static_cast<long long>(*n), elapsed,
              static_cast<double>(*n) >= elapsed - 1.0 ? "no second lost" : "SECONDS LOST");
  return static_cast<double>(*n) >= elapsed - 1.0 ? 0 : 1;
}
