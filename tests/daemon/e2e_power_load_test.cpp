// The gyros' power notes on a busy host: at time scale 200 with two busy loops beside the daemon
// and the mock bench, frames come late and in bursts and ticks are late, and none of it may read
// as a power cycle. Only the gyro's own start-up frames (warming_up, the counter from 0) date a
// power-on (docs/daemon.md "Power-on", docs/reliability.md). Live daemon and mock bench.
#include "live_bench.hpp"

#include <atomic>
#include <thread>

using namespace fogbench::daemon::test;
using namespace fogbench::daemon::test::live;

namespace {

// Busy loops on every core the test may share with the daemon and the bench, until destroyed.
struct BusyLoops {
  std::atomic<bool> stop{false};
  std::vector<std::thread> threads;
  explicit BusyLoops(int n) {
    for (int i = 0; i < n; ++i)
      threads.emplace_back([this] {
        volatile std::uint64_t x = 0;
        while (!stop.load(std::memory_order_relaxed)) x = x + 1;
      });
  }
  ~BusyLoops() {
    stop = true;
    for (auto& t : threads) t.join();
  }
};

}  // namespace

TEST_CASE("e2e power under load: at time scale 200 with two busy loops a run has no false power note and its time since power-on only grows") {
  require_sim();
  LiveBench bench(200.0);
  INFO("test dir " << bench.dir);
  BusyLoops busy(2);
  LineClient c(bench.socket());
  REQUIRE(c.ok());
  // SIM-0001 power-cycled before the run, under the load: its start-up frames tell the daemon
  // when, so the run's samples all have a time since power-on. SIM-0002 was on before the daemon.
  REQUIRE(bench.sim_command({{"cmd", "fault"}, {"name", "power_cycle"}, {"unit", 0}, {"off_s", 5}})["ok"] == true);
  const auto deadline = SteadyClock::now() + 120s;
  bool seen = false;
  while (!seen && SteadyClock::now() < deadline) {
    std::this_thread::sleep_for(200ms);
    const json sim = bench.sim_command({{"cmd", "status"}});
    seen = sim.is_object() && sim["units"][0]["powered"] == true && sim["units"][0]["powered_on_at_s"].get<double>() > 0.0;
  }
  REQUIRE(seen);
  std::this_thread::sleep_for(1s);  // 200 simulated s: the daemon has read the start-up since
  const auto run = bench.start_run(c, "short", {"SIM-0001", "SIM-0002"});
  const json done = bench.wait_state(c, run, {"completed", "aborted", "failed", "interrupted"}, 600s);
  INFO(done.dump());
  REQUIRE(done.contains("result"));
  REQUIRE(done["result"]["run"]["state"] == "completed");

  // The notes: SIM-0001 on since before the run, SIM-0002's power-on not seen; nothing else.
  std::vector<json> notes;
  for (const auto& e : done["result"]["events"])
    if (e["kind"] == "note" && e["detail"].contains("gyro_power")) notes.push_back(e["detail"]);
  INFO("power notes: " << json(notes).dump());
  REQUIRE(notes.size() == 2);
  for (const auto& n : notes) {
    if (n["unit"] == 0) {
      CHECK(n["gyro_power"] == "on");
      CHECK(n["since_power_on_s"].get<double>() > 0.0);
    } else {
      CHECK(n["gyro_power"] == "power_on_not_seen");
    }
  }

  // SIM-0001's time since power-on: known in every sample and growing exactly with the run's
  // clock (never reset, never unknown); SIM-0002's never known, never guessed.
  std::size_t empty_seconds = 0;
  for (int unit = 0; unit < 2; ++unit) {
    std::vector<json> rows;
    for (int offset = 0;; offset += 10000) {
      auto page = c.call({{"cmd", "run.samples"}, {"run_id", run}, {"unit", unit}, {"offset", offset}, {"limit", 10000}});
      REQUIRE(code_of(page) == "ok");
      for (auto& s : page["result"]["samples"]) rows.push_back(s);
      if (page["result"]["samples"].size() < 10000) break;
    }
    REQUIRE(rows.size() > 1800);
    for (std::size_t i = 0; i < rows.size(); ++i) {
      empty_seconds += rows[i]["frames"] == 0;
      if (unit == 1) {
        if (!rows[i]["since_power_on_s"].is_null()) FAIL("SIM-0002 has a time since power-on at t_s " << rows[i]["t_s"]);
        continue;
      }
      if (!rows[i]["since_power_on_s"].is_number()) FAIL("SIM-0001's time since power-on unknown at t_s " << rows[i]["t_s"]);
      const double offset_s = rows[i]["since_power_on_s"].get<double>() - rows[i]["t_s"].get<double>();
      const double first_s = rows[0]["since_power_on_s"].get<double>() - rows[0]["t_s"].get<double>();
      if (std::abs(offset_s - first_s) > 1e-6) FAIL("SIM-0001's time since power-on jumps at t_s " << rows[i]["t_s"]);
    }
  }
  // What the load did: seconds in which no frame came (each one a "silence" a timing rule reads).
  WARN("seconds with no frames under the load: " << empty_seconds);
}
