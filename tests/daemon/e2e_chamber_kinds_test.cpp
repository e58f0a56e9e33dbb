// The real fogbenchd on a mock bench whose chamber speaks an ASCII dialect (fogbench-sim
// --chamber-dialect espec|simserv; the daemon's configuration is the one the bench prints, with
// "kind"): the daemon opens the chamber by kind, brings it up, runs a profile on it, and applies
// the same fault policies as for a Modbus chamber (an alarm aborts, the safe setpoint follows).
// Every wait has a deadline sized for a loaded machine.
#include "live_bench.hpp"

using namespace fogbench;
using namespace fogbench::daemon::test;
using namespace fogbench::daemon::test::live;
using nlohmann::json;
using namespace std::chrono_literals;

namespace {

bool running(const json& r) { return r["run"].is_object() && r["run"]["state"] == "running"; }

}  // namespace

TEST_CASE("e2e chamber kinds: an Espec or SIMSERV chamber runs a profile, its alarm aborts, the safe setpoint follows") {
  require_sim();
  const std::string dialect = GENERATE(as<std::string>{}, "espec", "simserv");
  INFO("dialect " << dialect);
  json patch;
  patch["drivers"]["chamber"]["link"]["backoff"] = {{"initial_ms", 20}, {"max_ms", 100}, {"multiplier", 2}};
  LiveBench bench(50.0, patch, false, nullptr, {"--chamber-dialect", dialect});
  REQUIRE(bench.ready_sim["drivers_config"]["chamber"]["kind"] == dialect);
  LineClient c(bench.socket());
  REQUIRE(c.ok());
  const auto run = bench.start_run(c, "short", {"SIM-0001"});
  // Into the ramp: the setpoint went out in the dialect and the air follows it.
  auto s = bench.wait_status(c, [](const json& r) {
    return running(r) && r["chamber"]["setpoint_c"].is_number() && r["chamber"]["setpoint_c"].get<double>() > 21.0;
  }, 120s);
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
