// fogbenchd's `status` reply latency with many clients connected while a run acquires: the
// mock bench serves 8 units, a run stores all 8 every second (one SQLite transaction with
// synchronous=FULL), 50 clients are subscribed and receive every sample, and one of them times
// `status` round trips.
// Usage: bench_daemon_status [clients=50] [requests=2000] [time_scale=1] [synchronous=full|normal]
#include <poll.h>

#include <atomic>
#include <thread>

#include "daemon_bench.hpp"

using namespace fogbench::bench;

int main(int argc, char** argv) {
  const int clients = argc > 1 ? std::atoi(argv[1]) : 50;
  const int requests = argc > 2 ? std::atoi(argv[2]) : 2000;
  const double scale = argc > 3 ? std::atof(argv[3]) : 1.0;
  const std::string sync = argc > 4 ? argv[4] : "full";
  const int units = 8;
  LiveBench bench(argv[0], units, scale, sync);

  std::vector<std::unique_ptr<LineClient>> conns;
  for (int i = 0; i < clients; ++i) {
    conns.push_back(std::make_unique<LineClient>(bench.socket()));
    if (!conns.back()->ok()) LiveBench::fail("connect failed");
    if (!conns.back()->line(10s)) LiveBench::fail("no hello");
  }
  json units_json = json::array();
  for (int u = 1; u <= units; ++u) {
    char serial[16];
    std::snprintf(serial, sizeof serial, "SIM-%04d", u);
    units_json.push_back(serial);
  }
  auto start = conns[0]->call({{"cmd", "run.start"}, {"profile", "exp1"}, {"units", units_json}});
  if (!start.is_object() || !start.contains("result")) LiveBench::fail("run.start: " + start.dump());
  for (int i = 0; i < clients; ++i) conns[i]->call({{"cmd", "subscribe"}});

  // The other clients drain their pushed samples, as a live display would.
  std::atomic<bool> stop{false};
  std::thread drain([&] {
    while (!stop) {
      for (int i = 1; i < clients; ++i) conns[i]->line(0ms);
      std::this_thread::sleep_for(5ms);
    }
  });

  std::this_thread::sleep_for(2s);  // the run under way
  std::vector<double> ms;
  for (int i = 0; i < requests; ++i) {
    const auto t0 = std::chrono::steady_clock::now();
    auto r = conns[0]->call({{"cmd", "status"}}, 10s);
    const auto t1 = std::chrono::steady_clock::now();
    if (!r.is_object() || !r.contains("result")) LiveBench::fail("status failed");
    ms.push_back(std::chrono::duration<double, std::milli>(t1 - t0).count());
    std::this_thread::sleep_for(3ms);  // spread over many acquisition ticks
  }
  const auto run = start["result"]["run_id"].get<std::int64_t>();
  auto got = conns[0]->call({{"cmd", "run.get"}, {"run_id", run}});
  stop = true;
  drain.join();
  std::printf("status reply latency, %d clients subscribed, run acquiring %d units (time scale %g, synchronous=%s), "
              "%d requests:\n", clients, units, scale, sync.c_str(), requests);
  std::printf("  p50 %.3f ms  p90 %.3f ms  p99 %.3f ms  max %.3f ms\n", percentile(ms, 50), percentile(ms, 90),
              percentile(ms, 99), percentile(ms, 100));
  if (got.contains("result"))
    std::printf("  run %lld stored %s samples per unit meanwhile\n", static_cast<long long>(run),
                got["result"]["samples"][0].dump().c_str());
  return 0;
}
