// The mock bench's Modbus side driven by the drivers' real clients: the chamber follows a
// written setpoint, the thermistor module reads plausible coil temperatures in both of the
// example configuration's encodings, several clients are served at once, and each Modbus fault
// reaches the client as the error value it should.
#include <catch2/catch.hpp>

#include <atomic>
#include <thread>

#include "fogbench/drivers/chamber.hpp"
#include "fogbench/drivers/thermistor_module.hpp"
#include "mock_process.hpp"

using namespace fogbench::drivers;
using namespace mockbench;

TEST_CASE("the chamber's process value follows a written setpoint, and the status bits say so") {
  // K = 100: 20 -> 35 degC is 3 min at the chamber's 5 degC/min plus the tail of its 60 s lag,
  // about 3 s of wall time.
  MockProcess mock({"--time-scale", "100"});
  auto cfg = mock.example_config();
  ModbusChamber chamber(cfg.chamber);
  auto report = chamber.bring_up();
  REQUIRE(report.has_value());
  INFO(report->to_string());
  CHECK(report->ok());

  // At rest at --start-c (20 degC): the reading carries 0.02 degC of noise, so 0.1 is 5 sigma.
  auto pv0 = chamber.read_process_value_c();
  REQUIRE(pv0.has_value());
  CHECK(*pv0 == Approx(20.0).margin(0.1));

  REQUIRE(chamber.write_setpoint_c(35.0).has_value());
  CHECK(*chamber.read_setpoint_c() == 35.0);  // float32 holds 35 exactly
  bool heating_seen = false;
  const bool reached = wait_for(30s, [&] {
    auto r = chamber.poll();
    if (!r) return false;
    for (const auto& [name, on] : r->status->bits) heating_seen |= name == "heating" && on;
    return std::abs(r->process_value_c - 35.0) < 0.2;
  });
  CHECK(reached);
  CHECK(heating_seen);
  CHECK(mock.status()["setpoint_c"] == 35.0);
  // Settled (the lag's tail is 60 s): at_setpoint within a few simulated minutes.
  CHECK(wait_for(30s, [&] {
    auto s = chamber.read_status();
    return s && (s->raw & 0b100) != 0;
  }));

  // Stopped, the chamber no longer controls: the air drifts back towards the room (20 degC).
  REQUIRE(chamber.set_running(false).has_value());
  CHECK(*chamber.read_running() == false);
  CHECK(wait_for(30s, [&] {
    auto pv = chamber.read_process_value_c();
    return pv && *pv < 25.0;
  }));
  CHECK(mock.status()["running"] == false);
}

TEST_CASE("the thermistor module reads both encodings of the example configuration") {
  MockProcess mock({"--time-scale", "100", "--coil", "lumped"});  // the two-node coil's time constants below
  auto cfg = mock.example_config();
  ThermistorModule module(cfg.thermistors, cfg.units);
  auto r = module.read_all();
  REQUIRE(r.has_value());
  REQUIRE(r->size() == 2);
  // At rest at 20 degC: thermistor noise 0.005 degC, int16 steps of 0.01 degC (FOG-0001) and a
  // float32 resistance near 12.5 kohm through Steinhart-Hart (FOG-0002): 0.05 covers all.
  for (const auto& u : *r) {
    INFO(u.serial);
    REQUIRE(u.t1_c.has_value());
    REQUIRE(u.t2_c.has_value());
    CHECK(*u.t1_c == Approx(20.0).margin(0.05));
    CHECK(*u.t2_c == Approx(20.0).margin(0.05));
  }

  // Heating: the outer wall (T2) follows the air with 150 s, the centre (T1) the wall with 40 s,
  // so on the way up air > T2 > T1 > 20.
  ModbusChamber chamber(cfg.chamber);
  REQUIRE(chamber.write_setpoint_c(60.0).has_value());
  mock.wait_sim_time(mock.sim_time() + 200);
  auto up = module.read_all();
  REQUIRE(up.has_value());
  const auto st = mock.status();
  for (std::size_t i = 0; i < 2; ++i) {
    const auto& u = (*up)[i];
    INFO(u.serial);
    REQUIRE(u.t1_c.has_value());
    REQUIRE(u.t2_c.has_value());
    CHECK(*u.t2_c > *u.t1_c + 0.1);
    CHECK(*u.t1_c > 20.5);
    CHECK(*u.t2_c < st["air_c"].get<double>());
  }
}

TEST_CASE("several Modbus clients are served at once, and a stalled one blocks no other") {
  MockProcess mock({"--time-scale", "50"});
  auto cfg = mock.example_config(3000);
  std::vector<std::unique_ptr<ModbusChamber>> chambers;
  for (int i = 0; i < 3; ++i) chambers.push_back(std::make_unique<ModbusChamber>(cfg.chamber));
  ThermistorModule module(cfg.thermistors, cfg.units);
  for (int round = 0; round < 3; ++round) {
    for (auto& c : chambers) REQUIRE(c->read_process_value_c().has_value());
    REQUIRE(module.read_all().has_value());
  }
  CHECK(mock.status()["modbus_clients"] == 4);

  // Chamber replies stalled 600 ms; the thermistor module, on its own port, answers meanwhile.
  mock.fault({{"name", "stall_modbus"}, {"device", "chamber"}, {"ms", 600}});
  std::atomic<bool> done{false};
  Result<double> stalled = 0.0;
  std::thread t([&] {
    stalled = chambers[0]->read_process_value_c();
    done = true;
  });
  std::this_thread::sleep_for(100ms);  // let the request reach the bench first
  const auto t0 = std::chrono::steady_clock::now();
  auto temps = module.read_all();
  const auto took = std::chrono::steady_clock::now() - t0;
  t.join();
  REQUIRE(temps.has_value());
  CHECK(took < 400ms);
  // The stalled reply came late but whole (the client waits up to 3 s).
  REQUIRE(stalled.has_value());
  CHECK(*stalled == Approx(20.0).margin(0.1));
}

TEST_CASE("fault refuse_modbus: a connect is refused (a connection error value), cleared it connects") {
  MockProcess mock({"--time-scale", "50"});
  auto cfg = mock.example_config();
  mock.fault({{"name", "refuse_modbus"}, {"device", "chamber"}});
  {
    ModbusChamber chamber(cfg.chamber);
    auto r = chamber.read_process_value_c();
    REQUIRE_FALSE(r.has_value());
    CHECK(r.error().code == ErrorCode::connection);
    CHECK(r.error().message.find("connect:") != std::string::npos);
    // The thermistor module has its own listener and still answers.
    ThermistorModule module(cfg.thermistors, cfg.units);
    CHECK(module.read_all().has_value());
  }
  mock.fault({{"name", "refuse_modbus"}, {"on", false}});
  ModbusChamber chamber(cfg.chamber);
  CHECK(chamber.read_process_value_c().has_value());
}

TEST_CASE("fault drop_modbus: the connected client gets a connection error, then reconnects") {
  MockProcess mock({"--time-scale", "50"});
  auto cfg = mock.example_config();
  ModbusChamber chamber(cfg.chamber);
  REQUIRE(chamber.read_process_value_c().has_value());
  mock.fault({{"name", "drop_modbus"}});
  auto r = chamber.read_process_value_c();
  REQUIRE_FALSE(r.has_value());
  INFO(r.error().to_string());
  CHECK(r.error().code == ErrorCode::connection);
  CHECK_FALSE(chamber.link().is_connected());
  // The backoff is 20 ms here: the next calls reconnect.
  CHECK(wait_for(5s, [&] { return chamber.read_process_value_c().has_value(); }));
}

TEST_CASE("fault stall_modbus: a reply later than the client's timeout is a timeout value") {
  MockProcess mock({"--time-scale", "50"});
  auto cfg = mock.example_config(100);
  ThermistorModule module(cfg.thermistors, cfg.units);
  REQUIRE(module.read_all().has_value());
  mock.fault({{"name", "stall_modbus"}, {"device", "thermistors"}, {"ms", 400}});
  auto r = module.read_all();
  REQUIRE_FALSE(r.has_value());
  CHECK(r.error().code == ErrorCode::timeout);
  mock.fault({{"name", "stall_modbus"}, {"on", false}});
  CHECK(wait_for(5s, [&] { return module.read_all().has_value(); }));
}

TEST_CASE("fault freeze_pv: the process value stays put while the air moves") {
  MockProcess mock({"--time-scale", "100"});
  auto cfg = mock.example_config();
  ModbusChamber chamber(cfg.chamber);
  mock.fault({{"name", "freeze_pv"}});
  const auto frozen = chamber.read_process_value_c();
  REQUIRE(frozen.has_value());
  REQUIRE(chamber.write_setpoint_c(40.0).has_value());
  // 5 degC of real movement takes the air a minute at 5 degC/min.
  CHECK(wait_for(30s, [&] { return mock.status()["air_c"].get<double>() > 25.0; }));
  CHECK(*chamber.read_process_value_c() == *frozen);  // bit for bit: nobody wrote it
  CHECK(mock.status()["faults"][0]["name"] == "freeze_pv");
  mock.fault({{"name", "freeze_pv"}, {"on", false}});
  CHECK(wait_for(10s, [&] { return *chamber.read_process_value_c() > 25.0; }));
}

TEST_CASE("fault alarm: the chamber's alarm reads true and fails bring-up") {
  MockProcess mock({"--time-scale", "50"});
  auto cfg = mock.example_config();
  ModbusChamber chamber(cfg.chamber);
  CHECK(*chamber.read_alarm() == false);
  mock.fault({{"name", "alarm"}});
  CHECK(*chamber.read_alarm() == true);
  auto report = chamber.bring_up();
  REQUIRE(report.has_value());
  for (const auto& c : report->checks) {
    INFO(c.name << ": " << c.detail);
    CHECK(c.ok == (c.name != "alarm"));
  }
  mock.fault({{"name", "alarm"}, {"on", false}});
  CHECK(*chamber.read_alarm() == false);
}

TEST_CASE("fault open_thermistor: that unit's sensor is an open-circuit error, the others read") {
  MockProcess mock({"--time-scale", "50"});
  auto cfg = mock.example_config();
  ThermistorModule module(cfg.thermistors, cfg.units);
  // FOG-0002 T2 is an NTC: the bench serves ten times the declared open resistance.
  mock.fault({{"name", "open_thermistor"}, {"unit", 1}, {"sensor", "t2"}});
  auto r = module.read_all();
  REQUIRE(r.has_value());
  CHECK((*r)[0].t1_c.has_value());
  CHECK((*r)[0].t2_c.has_value());
  CHECK((*r)[1].t1_c.has_value());
  REQUIRE_FALSE((*r)[1].t2_c.has_value());
  CHECK((*r)[1].t2_c.error().code == ErrorCode::open_circuit);
  CHECK((*r)[1].t2_c.error().message.starts_with("unit FOG-0002 T2: open circuit"));

  // FOG-0001 T1 is an int16 channel: the bench serves its declared open_circuit_raw, 32767.
  mock.fault({{"name", "open_thermistor"}, {"unit", "SIM-0001"}, {"sensor", "t1"}});
  r = module.read_all();
  REQUIRE(r.has_value());
  REQUIRE_FALSE((*r)[0].t1_c.has_value());
  CHECK((*r)[0].t1_c.error().code == ErrorCode::open_circuit);
  CHECK((*r)[0].t1_c.error().message.starts_with("unit FOG-0001 T1: open circuit"));

  mock.fault({{"name", "open_thermistor"}, {"on", false}});
  r = module.read_all();
  REQUIRE(r.has_value());
  for (const auto& u : *r) {
    CHECK(u.t1_c.has_value());
    CHECK(u.t2_c.has_value());
  }
}

TEST_CASE("the gateway mode serves the thermistor module on the chamber's port by unit id") {
  MockProcess mock({"--gateway", "--time-scale", "50"});
  CHECK(mock.thermistor_port() == mock.chamber_port());
  auto cfg = mock.example_config();
  ThermistorModule module(cfg.thermistors, cfg.units);
  auto r = module.read_all();
  REQUIRE(r.has_value());
  CHECK(*(*r)[0].t1_c == Approx(20.0).margin(0.05));
  ModbusChamber chamber(cfg.chamber);
  CHECK(chamber.read_process_value_c().has_value());
  // A unit id the gateway does not have: an exception, a protocol error, the link stays up.
  auto other = cfg.chamber;
  other.modbus.unit_id = 7;
  ModbusChamber stranger(other);
  auto e = stranger.read_process_value_c();
  REQUIRE_FALSE(e.has_value());
  CHECK(e.error().code == ErrorCode::protocol);
  CHECK(stranger.link().is_connected());
}

TEST_CASE("fogbench-sim --axis-thermistors: the module serves each axis's coil, y's and z's lagging x's on a ramp", "[three_axis][axis_thermistors]") {
  MockProcess mock({"--time-scale", "100", "--coil", "lumped", "--units", "2", "--axes", "3", "--axis-thermistors"});
  CHECK(mock.ready()["units"][0]["axis_thermistors"] == true);
  // The ready line's drivers configuration names the six channels of each unit.
  auto cfg = parse_drivers_config(mock.ready()["drivers_config"], FOGBENCH_SOURCE_DIR "/drivers/maps");
  INFO((cfg ? std::string() : cfg.error().to_string()));
  REQUIRE(cfg.has_value());
  ThermistorModule module(cfg->thermistors, cfg->units);
  auto r = module.read_all();
  REQUIRE(r.has_value());
  REQUIRE(r->size() == 2);
  for (const auto& u : *r) {  // at rest at 20 degC, both encodings (int16, NTC float32): as above
    INFO(u.serial);
    REQUIRE(u.axis_t1_c.size() == 2);
    for (const auto* v : {&u.t1_c, &u.t2_c, &u.axis_t1_c[0], &u.axis_t2_c[0], &u.axis_t1_c[1], &u.axis_t2_c[1]}) {
      REQUIRE(v->has_value());
      CHECK(**v == Approx(20.0).margin(0.05));
    }
  }
  // Heating: y's coil (paths 1.6x x's) behind x's, z's (2.4x) behind y's.
  ModbusChamber chamber(cfg->chamber);
  REQUIRE(chamber.write_setpoint_c(60.0).has_value());
  REQUIRE(chamber.set_running(true).has_value());
  mock.wait_sim_time(mock.sim_time() + 300);
  auto up = module.read_all();
  REQUIRE(up.has_value());
  for (const auto& u : *up) {
    INFO(u.serial);
    REQUIRE(u.t1_c.has_value());
    REQUIRE(u.axis_t1_c[0].has_value());
    REQUIRE(u.axis_t1_c[1].has_value());
    CHECK(*u.t1_c > *u.axis_t1_c[0] + 0.3);
    CHECK(*u.axis_t1_c[0] > *u.axis_t1_c[1] + 0.3);
  }
}
