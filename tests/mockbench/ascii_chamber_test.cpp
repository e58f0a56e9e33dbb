// The mock bench's ASCII chamber controllers: how each dialect answers (no I/O, from the served
// registers), and the real drivers against the real fogbench-sim in each dialect, with the
// chamber faults the daemon handles (link loss, frozen value, refused setpoint, alarm).
#include <catch2/catch.hpp>

#include "ascii_chamber.hpp"
#include "fogbench/drivers/chamber_dialects.hpp"
#include "fogbench/drivers/chamber_registry.hpp"
#include "fogbench/drivers/config.hpp"
#include "layout.hpp"
#include "mock_process.hpp"
#include "options.hpp"
#include "registers.hpp"

using namespace fogbench::drivers;
using namespace fogbench::mock;
using mockbench::MockProcess;
using mockbench::wait_for;
using namespace std::chrono_literals;

namespace {

const std::string B6 = "\xB6";

ChamberRegisters mock_chamber(double setpoint_c = 20.0) {
  auto map = load_served_map("");
  REQUIRE(map);
  auto regs = ChamberRegisters::create(map->map, setpoint_c, true);
  REQUIRE(regs);
  return std::move(*regs);
}

// The chamber section the bench's ready line gives for its dialect, parsed as the daemon
// would, with a short timeout and a quick reconnection (the tests wait on real time).
ChamberConfig served_chamber(const MockProcess& mock, int timeout_ms = 500) {
  auto j = mock.ready()["drivers_config"]["chamber"];
  if (j.contains("link")) {
    j["link"]["response_timeout_ms"] = timeout_ms;
    j["link"]["backoff"] = {{"initial_ms", 20}, {"max_ms", 200}, {"multiplier", 2}};
  } else {
    j["modbus"]["response_timeout_ms"] = timeout_ms;
    j["modbus"]["backoff"] = {{"initial_ms", 20}, {"max_ms", 200}, {"multiplier", 2}};
  }
  auto cfg = parse_chamber_config(j, "chamber", FOGBENCH_SOURCE_DIR "/drivers/maps");
  INFO((cfg ? std::string() : cfg.error().to_string()));
  REQUIRE(cfg);
  return *cfg;
}

std::unique_ptr<Chamber> open_served(const MockProcess& mock, int timeout_ms = 500) {
  auto chamber = open_chamber(served_chamber(mock, timeout_ms));
  REQUIRE(chamber);
  return std::move(*chamber);
}

}  // namespace

// ---- answers, no I/O -----------------------------------------------------------------------

TEST_CASE("mock espec controller: answers from the served registers, errors as the controller's") {
  auto regs = mock_chamber(20.0);
  CHECK(answer_espec("TEMP?", regs, false) == "20.0,20.0,250.0,-100.0\r\n");
  CHECK(answer_espec("MON?", regs, false) == "20.0,,CONSTANT,0\r\n");
  CHECK(answer_espec("TEMP, S-40.0", regs, false) == "OK:TEMP,S-40.0\r\n");
  CHECK(regs.setpoint_c(0) == -40.0);
  CHECK(answer_espec("TEMP,S-41.5", regs, false) == "OK:TEMP,S-41.5\r\n");
  CHECK(answer_espec("TEMP, S300", regs, false) == "NA:DATA OUT OF RANGE\r\n");
  CHECK(answer_espec("TEMP, S25", regs, true) == "NA:DATA OUT OF RANGE\r\n");  // refuse_setpoint
  CHECK(regs.setpoint_c(0) == -41.5);
  CHECK(answer_espec("TEMP, Swarm", regs, false) == "NA:PARA ERR\r\n");
  CHECK(answer_espec("MODE, STANDBY", regs, false) == "OK:MODE,STANDBY\r\n");
  CHECK_FALSE(regs.running());
  CHECK(answer_espec("MODE?", regs, false) == "STANDBY\r\n");
  regs.show_alarm(true);
  CHECK(answer_espec("ALARM?", regs, false) == "1,1\r\n");
  CHECK(answer_espec("HUMI?", regs, false) == "NA:CMD ERR\r\n");
  CHECK(answer_espec("11004" + B6 + "1" + B6 + "1", regs, false) == "NA:CMD ERR\r\n");
}

TEST_CASE("mock simserv controller: answers from the served registers, errors as the controller's") {
  auto regs = mock_chamber(20.0);
  auto cmd = [](std::string s) { return s; };
  CHECK(answer_simserv(cmd("11004" + B6 + "1" + B6 + "1"), regs, false) == "1" + B6 + "20.0\r\n");
  CHECK(answer_simserv(cmd("11001" + B6 + "1" + B6 + "1" + B6 + "-40.0"), regs, false) == "1\r\n");
  CHECK(regs.setpoint_c(0) == -40.0);
  CHECK(answer_simserv(cmd("11002" + B6 + "1" + B6 + "1"), regs, false) == "1" + B6 + "-40.0\r\n");
  CHECK(answer_simserv(cmd("11001" + B6 + "1" + B6 + "1" + B6 + "20.0"), regs, true) == "-6\r\n");
  CHECK(answer_simserv(cmd("11001" + B6 + "1" + B6 + "1" + B6 + "999"), regs, false) == "-6\r\n");
  CHECK(answer_simserv(cmd("10012" + B6 + "1"), regs, false) == "1" + B6 + "3\r\n");
  CHECK(answer_simserv(cmd("14001" + B6 + "1" + B6 + "1" + B6 + "0"), regs, false) == "1\r\n");
  regs.show_alarm(true);
  CHECK(answer_simserv(cmd("10012" + B6 + "1"), regs, false) == "1" + B6 + "9\r\n");
  CHECK(answer_simserv("TEMP?", regs, false) == "-5\r\n");
  CHECK(answer_simserv(cmd("12345" + B6 + "1"), regs, false) == "-5\r\n");
  CHECK(answer_simserv(cmd("11004" + B6 + "2" + B6 + "1"), regs, false) == "-6\r\n");
}

TEST_CASE("fogbench-sim --chamber-dialect: an unknown dialect is refused, and gateway needs modbus") {
  Options o;
  o.chamber_dialect = "thermotron";
  CHECK(make_bench_config(o).error() == "--chamber-dialect: unknown dialect 'thermotron' (expected modbus, espec, simserv)");
  o.chamber_dialect = "espec";
  o.gateway = true;
  CHECK_THAT(make_bench_config(o).error(), Catch::StartsWith("--gateway needs --chamber-dialect modbus"));
}

// ---- the drivers against the real fogbench-sim ---------------------------------------------

TEST_CASE("ascii dialects: the driver brings up, commands and reads the simulated chamber") {
  const std::string dialect = GENERATE(as<std::string>{}, "espec", "simserv");
  INFO("dialect " << dialect);
  MockProcess mock({"--chamber-dialect", dialect, "--time-scale", "100"});
  CHECK(mock.ready()["chamber"]["dialect"] == dialect);
  CHECK(mock.ready()["drivers_config"]["chamber"]["kind"] == dialect);
  auto chamber = open_served(mock);
  auto report = chamber->bring_up();
  REQUIRE(report);
  INFO(report->to_string());
  CHECK(report->ok());
  REQUIRE(chamber->write_setpoint_c(40.0));
  auto r = chamber->poll();
  REQUIRE(r);
  CHECK(r->setpoint_c == 40.0);
  CHECK(r->running);
  // The physics takes the written setpoint at its next step.
  CHECK(wait_for(10s, [&] { return mock.status()["setpoint_c"].get<double>() == 40.0; }));
  // The physics follows the setpoint written over the dialect.
  CHECK(wait_for(30s, [&] {
    auto p = chamber->poll();
    return p && p->process_value_c > 25.0;
  }));
  REQUIRE(chamber->set_running(false));
  CHECK_FALSE(chamber->poll()->running);
  CHECK(wait_for(10s, [&] { return mock.status()["running"] == false; }));
}

TEST_CASE("ascii dialects: the chamber faults (frozen value, refused setpoint, alarm, link loss)") {
  const std::string dialect = GENERATE(as<std::string>{}, "espec", "simserv");
  INFO("dialect " << dialect);
  MockProcess mock({"--chamber-dialect", dialect, "--time-scale", "100"});
  auto chamber = open_served(mock, 300);

  SECTION("freeze_pv: the process value stays put while the air moves") {
    mock.fault({{"name", "freeze_pv"}});
    const auto frozen = chamber->poll();
    REQUIRE(frozen);
    REQUIRE(chamber->write_setpoint_c(40.0));
    CHECK(wait_for(30s, [&] { return mock.status()["air_c"].get<double>() > 25.0; }));
    CHECK(chamber->poll()->process_value_c == frozen->process_value_c);
    mock.fault({{"name", "freeze_pv"}, {"on", false}});
    CHECK(wait_for(10s, [&] { return chamber->poll()->process_value_c > 25.0; }));
  }
  SECTION("refuse_setpoint: the controller's refusal names device, command and reply") {
    mock.fault({{"name", "refuse_setpoint"}});
    auto w = chamber->write_setpoint_c(30.0);
    REQUIRE_FALSE(w);
    const std::string expected = dialect == "espec" ? "'TEMP, S30.0' refused: 'NA:DATA OUT OF RANGE'"
                                                    : "'11001<B6>1<B6>1<B6>30.0' answered '-6'";
    CHECK_THAT(w.error().message, Catch::StartsWith("chamber " + dialect + " (tcp 127.0.0.1:") &&
                                      Catch::Contains(expected));
    CHECK(chamber->poll()->setpoint_c == 20.0);  // nothing written
    mock.fault({{"name", "refuse_setpoint"}, {"on", false}});
    CHECK(chamber->write_setpoint_c(30.0));
  }
  SECTION("alarm: the poll shows it and the bring-up fails its check") {
    mock.fault({{"name", "alarm"}});
    CHECK(chamber->poll()->alarm);
    auto report = chamber->bring_up();
    REQUIRE(report);
    CHECK_FALSE(report->ok());
    CHECK_THAT(report->to_string(), Catch::Contains("FAIL alarm"));
  }
  SECTION("drop, refuse and stall: link errors, then the driver reconnects") {
    REQUIRE(chamber->poll());
    mock.fault({{"name", "drop_modbus"}, {"device", "chamber"}});
    auto dropped = chamber->poll();
    REQUIRE_FALSE(dropped);
    CHECK(dropped.error().code == ErrorCode::connection);
    mock.fault({{"name", "refuse_modbus"}, {"device", "chamber"}});
    CHECK(wait_for(5s, [&] {
      auto p = chamber->poll();
      return !p && p.error().message.find("Connection refused") != std::string::npos;
    }));
    mock.fault({{"name", "refuse_modbus"}, {"device", "chamber"}, {"on", false}});
    CHECK(wait_for(5s, [&] { return chamber->poll().has_value(); }));
    mock.fault({{"name", "stall_modbus"}, {"device", "chamber"}, {"ms", 1000}});
    auto stalled = chamber->poll();
    REQUIRE_FALSE(stalled);
    CHECK(stalled.error().code == ErrorCode::timeout);
    mock.fault({{"name", "stall_modbus"}, {"device", "chamber"}, {"on", false}});
    CHECK(wait_for(10s, [&] { return chamber->poll().has_value(); }));
  }
}

TEST_CASE("fault refuse_setpoint on the Modbus controller: an exception, the setpoint unchanged") {
  MockProcess mock({"--time-scale", "50"});
  ModbusChamber chamber(mock.example_config().chamber);
  mock.fault({{"name", "refuse_setpoint"}});
  auto w = chamber.write_setpoint_c(30.0);
  REQUIRE_FALSE(w);
  CHECK(w.error().code == ErrorCode::protocol);
  CHECK(*chamber.read_setpoint_c() == 20.0);
  CHECK(chamber.read_process_value_c().has_value());  // reads still answered
  mock.fault({{"name", "refuse_setpoint"}, {"on", false}});
  CHECK(chamber.write_setpoint_c(30.0).has_value());
}
