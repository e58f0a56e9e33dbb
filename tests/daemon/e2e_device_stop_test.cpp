// A stop that a device cannot hold (issue 27, point 3; docs/reliability.md "The stop's budget"):
// the chamber stops answering mid-run (the mock's stall_modbus, longer than the configured
// response timeout), so the device worker sits in one call for a minute and the safe setpoint
// queued behind it is never written. SIGTERM must still end fogbenchd within systemd's
// TimeoutStopSec=20 (the budget is 15 s), with exit status 1 and the chamber's failure in the
// log, not when the call returns. Live daemon and mock bench.
#include "live_bench.hpp"

#include <fstream>
#include <sstream>

using namespace fogbench::daemon::test;
using namespace fogbench::daemon::test::live;
using nlohmann::json;
using namespace std::chrono_literals;

namespace {

std::string device_stop_log(const std::filesystem::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

}  // namespace

TEST_CASE("e2e device stop: SIGTERM with the chamber not answering ends fogbenchd within TimeoutStopSec, status 1") {
  require_sim();
  // Each chamber call waits up to 60 s for its answer (the driver's bound): a device that hangs
  // for longer than the stop's whole budget.
  LiveBench bench(20.0, {{"drivers", {{"chamber", {{"modbus", {{"response_timeout_ms", 60000}}}}}}}});
  INFO("test dir " << bench.dir);
  LineClient c(bench.socket());
  REQUIRE(c.ok());
  const auto run = bench.start_run(c, "short", {"SIM-0001"});
  bench.wait_state(c, run, {"running"}, 60s);

  // The chamber stalls every answer by 120 s: the next poll holds the device worker.
  REQUIRE(bench.sim_command({{"cmd", "fault"}, {"name", "stall_modbus"}, {"device", "chamber"}, {"ms", 120000}})["ok"] ==
          true);
  std::this_thread::sleep_for(1500ms);  // 30 polls' worth at time scale 20: one is in its call

  const auto t0 = SteadyClock::now();
  const int rc = bench.daemon->stop(40s);  // SIGKILL (-1) only after 40 s
  const double took_s = std::chrono::duration<double>(SteadyClock::now() - t0).count();
  const std::string log = device_stop_log(bench.dir / "fogbenchd.log");
  INFO("exit " << rc << " after " << took_s << " s; log:\n" << log);
  CHECK(rc == 1);           // the safe setpoint was not confirmed
  CHECK(took_s < 20.0);     // systemd's TimeoutStopSec in the units (systemd/)
  CHECK(took_s > 4.0);      // it did wait for the chamber, its share of the budget
  CHECK(log.find("stopping: SIGTERM") != std::string::npos);
  CHECK(log.find("the chamber did not confirm the safe setpoint") != std::string::npos);
  // Lift the stall so the mock's own stop is quick.
  bench.sim_command({{"cmd", "fault"}, {"name", "stall_modbus"}, {"device", "chamber"}, {"on", false}});
}
