// Acquisition timing end to end. The shared simulated clock: fogbenchd paces fogbench-sim
// (--paced, the daemon's `sim_clock`), so a run on a host whose cores are taken by other
// processes goes slower but acquires exactly what it acquires on an idle host (docs/daemon.md,
// "Time scale"). And on the free-running clock, a stalled thermistor module does not cost the
// chamber's readings.
#include "fixture.hpp"
#include "live_bench.hpp"

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <thread>

using namespace fogbench::daemon::test;
using namespace fogbench::daemon::test::live;
using nlohmann::json;
using namespace std::chrono_literals;

namespace {

// Child processes that spin until destroyed: the "other work" of a busy host.
struct BusyLoops {
  std::vector<pid_t> pids;
  explicit BusyLoops(int n) {
    for (int i = 0; i < n; ++i) {
      const pid_t p = ::fork();
      if (p == 0) {
        volatile std::uint64_t x = 0;
        for (;;) x = x + 1;
      }
      if (p > 0) pids.push_back(p);
    }
  }
  ~BusyLoops() {
    for (pid_t p : pids) ::kill(p, SIGKILL);
    for (pid_t p : pids) ::waitpid(p, nullptr, 0);
  }
};

struct Outcome {
  json run;                         // run.get's run
  std::vector<std::vector<json>> samples;  // per unit, in time order
  double wall_s = 0;
};

// exp1 for both units on a fresh paced bench at time scale 200, seed 7; every stored sample.
Outcome run_exp1() {
  LiveBench bench(200.0, json::object(), true);
  INFO("test dir " << bench.dir);
  LineClient c(bench.socket());
  REQUIRE(c.ok());
  REQUIRE(json::parse(*c.line(10s))["type"] == "hello");
  const auto t0 = SteadyClock::now();
  const auto run = bench.start_run(c, "exp1", {"SIM-0001", "SIM-0002"});
  // exp1 is about 6000 s of run time, 30 s of wall time at K = 200 on an idle host. The
  // deadline allows a busy one ten times that: a paced run only slows down.
  json done = bench.wait_state(c, run, {"completed", "aborted", "failed", "interrupted"}, 400s);
  Outcome o;
  o.wall_s = std::chrono::duration<double>(SteadyClock::now() - t0).count();
  REQUIRE(done.contains("result"));
  o.run = done["result"]["run"];
  for (int unit = 0; unit < 2; ++unit) {
    std::vector<json> all;
    for (int offset = 0;; offset += 10000) {
      auto page = c.call({{"cmd", "run.samples"}, {"run_id", run}, {"unit", unit}, {"offset", offset}, {"limit", 10000}});
      REQUIRE(code_of(page) == "ok");
      for (auto& s : page["result"]["samples"]) all.push_back(s);
      if (page["result"]["samples"].size() < 10000) break;
    }
    o.samples.push_back(std::move(all));
  }
  return o;
}

}  // namespace

TEST_CASE("e2e acquisition: exp1 at time scale 200 with both cores busy completes with the samples of an idle host") {
  REQUIRE(have_sim());
  const Outcome idle = run_exp1();
  INFO("idle run: " << idle.run.dump());
  REQUIRE(idle.run["state"] == "completed");

  Outcome busy;
  {
    // Three spinning processes for two cores: fogbenchd and fogbench-sim get well under a
    // core each, which made unpaced runs at K = 200 skip seconds and fail their settle.
    BusyLoops loops(3);
    busy = run_exp1();
  }
  INFO("busy run: " << busy.run.dump());
  REQUIRE(busy.run["state"] == "completed");
  WARN("exp1 at K = 200: " << idle.wall_s << " s of wall time idle, " << busy.wall_s << " s with the cores busy");

  // Every stored sample equal, bit for bit, but its wall time: the same seed, the same world
  // stepped under the same setpoints, the same frames averaged per second.
  for (int unit = 0; unit < 2; ++unit) {
    const auto& a = idle.samples[static_cast<std::size_t>(unit)];
    const auto& b = busy.samples[static_cast<std::size_t>(unit)];
    INFO("unit " << unit);
    REQUIRE(a.size() >= 5400);  // a settle of at least 10 min, then 90 min
    REQUIRE(a.size() == b.size());
    std::size_t differing = 0, flagged = 0;
    for (std::size_t i = 0; i < a.size(); ++i) {
      json x = a[i], y = b[i];
      x.erase("wall_time");
      y.erase("wall_time");
      if (x != y) {
        if (differing == 0) UNSCOPED_INFO("first difference at " << i << ": " << x.dump() << " vs " << y.dump());
        ++differing;
      }
      flagged += a[i]["flags"].get<int>() != 0;
    }
    CHECK(differing == 0);
    CHECK(flagged == 0);  // paced, not a second is missed even on the busy host
  }
}

TEST_CASE("e2e acquisition: a stalled thermistor module leaves the chamber's readings of those seconds in place") {
  REQUIRE(have_sim());
  LiveBench bench(20.0);  // free-running: each device is polled on its own thread
  INFO("test dir " << bench.dir);
  LineClient c(bench.socket());
  REQUIRE(c.ok());
  REQUIRE(json::parse(*c.line(10s))["type"] == "hello");
  const auto run = bench.start_run(c, "short", {"SIM-0001"});
  bench.wait_status(c, [](const json& s) { return s["run"].is_object() && s["run"]["elapsed_s"].get<double>() > 20; }, 30s);
  // Each reply of the module 1.5 s late, past its 500 ms response timeout: every read of it
  // fails for 3 s of wall time (60 s of run time at K = 20).
  REQUIRE(bench.sim_command({{"cmd", "fault"}, {"name", "stall_modbus"}, {"ms", 1500}, {"device", "thermistors"}})["ok"] == true);
  std::this_thread::sleep_for(3s);
  REQUIRE(bench.sim_command({{"cmd", "fault"}, {"name", "stall_modbus"}, {"on", false}, {"device", "thermistors"}})["ok"] == true);
  std::this_thread::sleep_for(3s);
  REQUIRE(code_of(c.call({{"cmd", "run.abort"}, {"reason", "test done"}})) == "ok");
  auto page = c.call({{"cmd", "run.samples"}, {"run_id", run}, {"unit", 0}, {"limit", 10000}});
  REQUIRE(code_of(page) == "ok");
  int t1_missing = 0, chamber_missing = 0;
  for (const auto& s : page["result"]["samples"]) {
    if (s["t1_c"].is_null()) {
      ++t1_missing;
      chamber_missing += s["chamber_c"].is_null();
    }
  }
  INFO("seconds without T1: " << t1_missing << ", of them without the chamber: " << chamber_missing);
  CHECK(t1_missing >= 20);  // the stall was seen
  // The chamber answered all along; before each device had its own thread, its polls queued
  // behind the module's timeouts and these seconds lost the chamber's value too.
  CHECK(chamber_missing * 10 <= t1_missing);
}
