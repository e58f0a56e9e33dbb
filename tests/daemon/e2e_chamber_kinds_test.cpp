// The real fogbenchd on a mock bench whose chamber speaks an ASCII dialect (fogbench-sim
// --chamber-dialect espec|simserv; the daemon's configuration is the one the bench prints, with
// "kind"): the daemon opens the chamber by kind, brings it up, runs a profile on it, and applies
// the same fault policies as for a Modbus chamber (an alarm aborts, a link lost past the
// tolerance aborts with its gap flagged, the safe setpoint follows).
// Every wait has a deadline sized for a loaded machine.
#include "live_bench.hpp"

using namespace fogbench;
using namespace fogbench::daemon::test;
using namespace fogbench::daemon::test::live;
using nlohmann::json;
using namespace std::chrono_literals;

namespace {

bool running(const json& r) { return r["run"].is_object() && r["run"]["state"] == "running"; }

// A short reconnection back-off for the ASCII chamber's link (wall time, not the scaled clock).
json fast_reconnect(json patch = json::object()) {
  patch["drivers"]["chamber"]["link"]["backoff"] = {{"initial_ms", 20}, {"max_ms", 100}, {"multiplier", 2}};
  return patch;
}

// Waits until the run is into the ramp (the controller's setpoint above 21 degC, so that the safe
// 20 degC is observable); the status reply.
json into_ramp(LiveBench& bench, LineClient& c) {
  return bench.wait_status(c, [](const json& r) {
    return running(r) && r["chamber"]["setpoint_c"].is_number() && r["chamber"]["setpoint_c"].get<double>() > 21.0;
  }, 120s);
}

}  // namespace

TEST_CASE("e2e chamber kinds: an Espec or SIMSERV chamber runs a profile, its alarm aborts, the safe setpoint follows") {
  require_sim();
  const std::string dialect = GENERATE(as<std::string>{}, "espec", "simserv");
  INFO("dialect " << dialect);
  LiveBench bench(50.0, fast_reconnect(), false, nullptr, {"--chamber-dialect", dialect});
  REQUIRE(bench.ready_sim["drivers_config"]["chamber"]["kind"] == dialect);
  LineClient c(bench.socket());
  REQUIRE(c.ok());
  const auto run = bench.start_run(c, "short", {"SIM-0001"});
  // Into the ramp: the setpoint went out in the dialect and the air follows it.
  auto s = into_ramp(bench, c);
  INFO("fogbenchd log in " << (bench.dir / "fogbenchd.log"));
  REQUIRE(s["result"]["chamber"]["setpoint_c"].get<double>() > 21.0);
  CHECK(s["result"]["chamber"]["link"] == "up");
  auto sim = bench.sim_command({{"cmd", "status"}});
  CHECK(sim["chamber_clients"].get<int>() >= 1);

  REQUIRE(bench.sim_command({{"cmd", "fault"}, {"name", "alarm"}, {"on", true}})["ok"] == true);
  json done = bench.wait_state(c, run, {"completed", "aborted", "failed"}, 60s);
  CHECK(done["result"]["run"]["state"] == "aborted");
  // A loaded host may add "the acquisition fell behind real time (...)" ahead of the cause.
  CHECK_THAT(done["result"]["run"]["reason"].get<std::string>(), Catch::EndsWith("chamber alarm"));
  auto safe = bench.wait_status(c, [](const json& r) { return r["chamber"]["setpoint_c"] == 20.0; }, 60s);
  CHECK(safe["result"]["chamber"]["setpoint_c"] == 20.0);
}

TEST_CASE("e2e chamber kinds: an Espec or SIMSERV chamber's link lost past link_loss.tolerance_s aborts, the gap flagged, the safe setpoint follows the link back") {
  require_sim();
  const std::string dialect = GENERATE(as<std::string>{}, "espec", "simserv");
  INFO("dialect " << dialect);
  LiveBench bench(50.0, fast_reconnect({{"link_loss", {{"policy", "hold"}, {"tolerance_s", 20}}}}), false, nullptr,
                  {"--chamber-dialect", dialect});
  LineClient c(bench.socket());
  REQUIRE(c.ok());
  const auto run = bench.start_run(c, "short", {"SIM-0001"});
  auto s = into_ramp(bench, c);
  INFO("fogbenchd log in " << (bench.dir / "fogbenchd.log"));
  REQUIRE(s["result"]["chamber"]["setpoint_c"].get<double>() > 21.0);

  // The controller refuses new connections and drops the present one: the same policy as for a
  // Modbus chamber (e2e_faults_test), whatever the dialect.
  REQUIRE(bench.sim_command({{"cmd", "fault"}, {"name", "refuse_modbus"}, {"device", "chamber"}, {"on", true}})["ok"] == true);
  REQUIRE(bench.sim_command({{"cmd", "fault"}, {"name", "drop_modbus"}, {"device", "chamber"}})["ok"] == true);
  json done = bench.wait_state(c, run, {"completed", "aborted", "failed"}, 60s);
  REQUIRE(done.contains("result"));
  CHECK(done["result"]["run"]["state"] == "aborted");
  CHECK_THAT(done["result"]["run"]["reason"].get<std::string>(), Catch::Contains("link_loss.tolerance_s 20"));
  auto page = c.call({{"cmd", "run.samples"}, {"run_id", run}, {"limit", 10000}});
  REQUIRE(code_of(page) == "ok");
  int gap = 0;
  for (const auto& smp : page["result"]["samples"])
    if (smp["flags"].get<int>() & 8) {  // link_gap, and missing: no chamber value invented
      ++gap;
      CHECK((smp["flags"].get<int>() & 1) != 0);
      CHECK(smp["chamber_c"].is_null());
    }
  CHECK(gap >= 20);

  REQUIRE(bench.sim_command({{"cmd", "fault"}, {"name", "refuse_modbus"}, {"device", "chamber"}, {"on", false}})["ok"] == true);
  auto back = bench.wait_status(c, [](const json& r) { return r["chamber"]["link"] == "up" && r["chamber"]["setpoint_c"] == 20.0; }, 60s);
  CHECK(back["result"]["chamber"]["link"] == "up");
  CHECK(back["result"]["chamber"]["setpoint_c"] == 20.0);
}
