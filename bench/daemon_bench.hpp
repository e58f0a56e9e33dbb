// Shared by the daemon benchmarks: a temp dir with fogbench-sim and fogbenchd running on it (the
// executables next to the benchmark's own), and percentile arithmetic.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "../tests/daemon/process.hpp"

namespace fogbench::bench {

using daemon::test::LineClient;
using daemon::test::Process;
using nlohmann::json;
using namespace std::chrono_literals;

struct LiveBench {
  std::filesystem::path bin, dir;
  std::unique_ptr<Process> sim, daemon;
  json ready_daemon;  // fogbenchd's ready line (tcp_port, web_port)

  // `prepare`, when given, is called with the temp dir before fogbenchd starts (e.g. to fill the
  // store, fogbench.db, with stored runs). `patch` is merged into the configuration (merge_patch).
  LiveBench(const char* argv0, int units, double time_scale, const std::string& synchronous = "full",
            const std::function<void(const std::filesystem::path&)>& prepare = {}, const json& patch = json::object()) {
    bin = std::filesystem::absolute(argv0).parent_path();
    char tmpl[] = "/tmp/fogbench-bench-XXXXXX";
    dir = ::mkdtemp(tmpl);
    sim = std::make_unique<Process>(
        std::vector<std::string>{(bin / "fogbench-sim").string(), "--modbus-port", "0", "--thermistor-port", "0",
                                 "--can-socket", (dir / "can.sock").string(), "--units", std::to_string(units),
                                 "--time-scale", std::to_string(time_scale), "--log-level", "warn"},
        dir / "sim.log");
    const auto ready = sim->read_line(60s);
    if (ready.empty()) fail("fogbench-sim did not start (is it built next to this benchmark?)");
    const json r = json::parse(ready);
    json c = {{"simulated", true},
              {"storage", {{"path", "fogbench.db"}, {"synchronous", synchronous}}},
              {"socket", {{"path", "fogbenchd.sock"}}},
              {"chamber_limits", {{"min_c", -40}, {"max_c", 85}, {"max_rate_c_per_min", 3}}},
              {"safe_setpoint_c", 20},
              {"profile_dir", std::string(FOGBENCH_SOURCE_DIR) + "/profiles"},
              {"drivers", r["drivers_config"]}};
    c.merge_patch(patch);
    std::ofstream(dir / "fogbenchd.json") << c.dump(2);
    if (prepare) prepare(dir);
    daemon = std::make_unique<Process>(
        std::vector<std::string>{(bin / "fogbenchd").string(), "--config", (dir / "fogbenchd.json").string(),
                                 "--time-scale", std::to_string(time_scale), "--log-level", "warn"},
        dir / "fogbenchd.log");
    const auto line = daemon->read_line(60s);
    if (line.empty()) fail("fogbenchd did not start; log in " + (dir / "fogbenchd.log").string());
    ready_daemon = json::parse(line, nullptr, false);
  }
  ~LiveBench() {
    daemon.reset();
    sim.reset();
    std::error_code ec;
    if (!std::getenv("FOGBENCH_KEEP_BENCH_DIRS")) std::filesystem::remove_all(dir, ec);
  }
  std::filesystem::path socket() const { return dir / "fogbenchd.sock"; }
  [[noreturn]] static void fail(const std::string& why) {
    std::cerr << "bench: " << why << "\n";
    std::exit(2);
  }
};

// The p-th percentile (0..100) by the nearest-rank method.
inline double percentile(std::vector<double> v, double p) {
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  const auto rank = static_cast<std::size_t>(std::ceil(p / 100.0 * static_cast<double>(v.size())));
  return v[std::min(v.size() - 1, rank == 0 ? 0 : rank - 1)];
}

}  // namespace fogbench::bench
