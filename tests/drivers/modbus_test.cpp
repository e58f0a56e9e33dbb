// The chamber and thermistor drivers as real libmodbus clients against a libmodbus TCP server
// in a thread on 127.0.0.1: what lands in the registers, what is read back, and the failures a
// dead or silent server produces, as values.
#include <catch2/catch.hpp>

#include <nlohmann/json.hpp>

#include <bit>

#include "fogbench/drivers/chamber.hpp"
#include "fogbench/drivers/thermistor_module.hpp"
#include "modbus_test_server.hpp"

using namespace fogbench::drivers;
using namespace std::chrono_literals;
using nlohmann::json;

namespace {

const std::string map_dir = FOGBENCH_SOURCE_DIR "/drivers/maps/";

ModbusEndpoint local(std::uint16_t port, int timeout_ms = 1000) {
  ModbusEndpoint ep;
  ep.transport = ModbusEndpoint::Transport::tcp;
  ep.host = "127.0.0.1";
  ep.port = port;
  ep.response_timeout_ms = timeout_ms;
  ep.backoff = {250, 30000, 2.0};
  return ep;
}

ChamberConfig mock_chamber(std::uint16_t port, int timeout_ms = 1000) {
  ChamberConfig cfg;
  cfg.modbus = local(port, timeout_ms);
  auto map = load_register_map(map_dir + "mock.json");
  REQUIRE(map.has_value());
  cfg.map = *map;
  return cfg;
}

// Writes a float32 high word first, as the mock map's registers are.
void put_float(std::uint16_t* regs, float f) {
  const auto u = std::bit_cast<std::uint32_t>(f);
  regs[0] = static_cast<std::uint16_t>(u >> 16);
  regs[1] = static_cast<std::uint16_t>(u);
}

// A port where nothing listens: bind an ephemeral port and release it.
std::uint16_t unused_port() {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr);
  socklen_t len = sizeof addr;
  ::getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len);
  ::close(fd);
  return ntohs(addr.sin_port);
}

// The mock map needs 1 coil, 1 discrete input, 2 holding and 5 input registers; 16 of each.
struct MockChamberServer : ModbusTestServer {
  MockChamberServer() : ModbusTestServer(16, 16, 16, 16) {
    with_mapping([](modbus_mapping_t& m) {
      put_float(&m.tab_input_registers[0], 23.5f);  // process value
      m.tab_input_registers[2] = 0xF0B2;            // identity
      m.tab_input_registers[3] = 1;                 // units: degC
    });
  }
};

}  // namespace

TEST_CASE("chamber: a setpoint written lands in the map's holding registers") {
  MockChamberServer server;
  ModbusChamber chamber(mock_chamber(server.port()));
  REQUIRE(chamber.write_setpoint_c(-40.25).has_value());
  server.with_mapping([](modbus_mapping_t& m) {
    // -40.25 = -1.0100001b x 2^5: sign 1, exponent 127 + 5 = 0x84, so 0xC2210000, high word first.
    CHECK(m.tab_registers[0] == 0xC221);
    CHECK(m.tab_registers[1] == 0x0000);
  });
  auto back = chamber.read_setpoint_c();
  REQUIRE(back.has_value());
  CHECK(*back == -40.25);  // exactly representable in float32
}

TEST_CASE("chamber: process value, run, alarm and status are read through the map") {
  MockChamberServer server;
  ModbusChamber chamber(mock_chamber(server.port()));
  auto pv = chamber.read_process_value_c();
  REQUIRE(pv.has_value());
  CHECK(*pv == 23.5);

  CHECK(*chamber.read_alarm() == false);
  server.with_mapping([](modbus_mapping_t& m) { m.tab_input_bits[0] = 1; });
  CHECK(*chamber.read_alarm() == true);

  REQUIRE(chamber.set_running(true).has_value());
  server.with_mapping([](modbus_mapping_t& m) { CHECK(m.tab_bits[0] == 1); });
  CHECK(*chamber.read_running() == true);
  REQUIRE(chamber.set_running(false).has_value());
  CHECK(*chamber.read_running() == false);

  // 0b0101: heating (bit 0) and at_setpoint (bit 2).
  server.with_mapping([](modbus_mapping_t& m) { m.tab_input_registers[4] = 0b0101; });
  auto status = chamber.read_status();
  REQUIRE(status.has_value());
  CHECK(status->raw == 5);
  REQUIRE(status->bits.size() == 4);
  for (const auto& [name, on] : status->bits) {
    CHECK(on == (name == "heating" || name == "at_setpoint"));
  }

  auto all = chamber.poll();
  REQUIRE(all.has_value());
  CHECK(all->process_value_c == 23.5);
  CHECK(all->alarm);
  CHECK_FALSE(all->running);
}

TEST_CASE("chamber: a setpoint outside the configured limits is refused before any I/O") {
  auto cfg = mock_chamber(unused_port());  // nothing listens: an attempt would fail differently
  cfg.setpoint_limits_c = {-60.0, 150.0};
  ModbusChamber chamber(cfg);
  auto r = chamber.write_setpoint_c(151.0);
  REQUIRE_FALSE(r.has_value());
  CHECK(r.error().code == ErrorCode::out_of_range);
  CHECK_FALSE(chamber.link().is_connected());
  CHECK(chamber.link().backoff().consecutive_failures() == 0);
}

TEST_CASE("chamber: bring-up reports identity, units and a plausible process value") {
  MockChamberServer server;
  ModbusChamber chamber(mock_chamber(server.port()));
  auto report = chamber.bring_up();
  REQUIRE(report.has_value());
  INFO(report->to_string());
  CHECK(report->ok());
  // connection, identity, units, process_value, setpoint, run, alarm, status
  CHECK(report->checks.size() == 8);

  // The controller is set to degF and its probe reads 999 degC: two failed checks, one report.
  server.with_mapping([](modbus_mapping_t& m) {
    m.tab_input_registers[3] = 2;
    put_float(&m.tab_input_registers[0], 999.0f);
  });
  auto bad = chamber.bring_up();
  REQUIRE(bad.has_value());
  CHECK_FALSE(bad->ok());
  int failed = 0;
  for (const auto& c : bad->checks) {
    if (!c.ok) {
      ++failed;
      CHECK((c.name == "units" || c.name == "process_value"));
    }
  }
  CHECK(failed == 2);
}

TEST_CASE("chamber: an exception reply is a protocol error and the link stays up") {
  ModbusTestServer server(16, 16, 16, 16);
  auto cfg = mock_chamber(server.port());
  cfg.map.process_value.address = 500;  // beyond the server's 16 input registers
  ModbusChamber chamber(cfg);
  auto r = chamber.read_process_value_c();
  REQUIRE_FALSE(r.has_value());
  CHECK(r.error().code == ErrorCode::protocol);
  CHECK(r.error().message.find("read input 500..501") != std::string::npos);
  CHECK(chamber.link().is_connected());
  CHECK(chamber.read_alarm().has_value());
}

TEST_CASE("chamber: a stopped server gives connection errors, then retries under backoff") {
  auto server = std::make_unique<MockChamberServer>();
  const auto port = server->port();
  auto now = std::chrono::steady_clock::time_point{} + 1h;
  ModbusChamber chamber(mock_chamber(port), [&now] { return now; });
  REQUIRE(chamber.read_process_value_c().has_value());

  server->stop();
  auto r = chamber.read_process_value_c();
  REQUIRE_FALSE(r.has_value());
  CHECK(r.error().code == ErrorCode::connection);
  CHECK_FALSE(chamber.link().is_connected());
  CHECK(chamber.link().backoff().consecutive_failures() == 1);

  // Within the first 250 ms delay: refused at once, without an attempt.
  now += 100ms;
  auto gated = chamber.read_process_value_c();
  REQUIRE_FALSE(gated.has_value());
  CHECK(gated.error().code == ErrorCode::connection);
  CHECK(gated.error().message.find("next attempt in 150 ms") != std::string::npos);
  CHECK(chamber.link().backoff().consecutive_failures() == 1);

  // After it: a real attempt, refused by the kernel (nothing listens): the delay doubles.
  now += 150ms;
  auto refused = chamber.read_process_value_c();
  REQUIRE_FALSE(refused.has_value());
  CHECK(refused.error().code == ErrorCode::connection);
  CHECK(refused.error().message.find("connect:") != std::string::npos);
  CHECK(chamber.link().backoff().consecutive_failures() == 2);
  CHECK(chamber.link().backoff().remaining(now) == 500ms);
}

TEST_CASE("chamber: a server that never replies gives a timeout value") {
  // A listening socket that is never accepted: the kernel completes the TCP handshake, the
  // request sits unread, and the 100 ms response timeout expires.
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  REQUIRE(::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0);
  REQUIRE(::listen(fd, 4) == 0);
  socklen_t len = sizeof addr;
  ::getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len);

  ModbusChamber chamber(mock_chamber(ntohs(addr.sin_port), 100));
  auto r = chamber.read_process_value_c();
  REQUIRE_FALSE(r.has_value());
  CHECK(r.error().code == ErrorCode::timeout);
  CHECK(r.error().message.starts_with("chamber (tcp 127.0.0.1:"));
  CHECK_FALSE(chamber.link().is_connected());  // a late reply must not be read as the next one
  ::close(fd);
}

TEST_CASE("chamber: the Watlow F4 map writes a scaled int16 setpoint") {
  ModbusTestServer server(0, 0, 2048, 0);  // the F4 keeps everything in holding registers
  ChamberConfig cfg;
  cfg.modbus = local(server.port());
  auto map = load_register_map(map_dir + "watlow-f4.json");
  REQUIRE(map.has_value());
  cfg.map = *map;
  ModbusChamber chamber(cfg);
  REQUIRE(chamber.write_setpoint_c(-12.5).has_value());
  // -12.5 / 0.1 = -125 = 0xFF83 in register 300.
  server.with_mapping([](modbus_mapping_t& m) {
    CHECK(m.tab_registers[300] == 0xFF83);
    m.tab_registers[100] = 0x00FB;  // input 1: 251 -> 25.1 degC
    m.tab_registers[102] = 2;       // alarm 1 status: high alarm
    m.tab_registers[0] = 5270;
    m.tab_registers[901] = 1;
  });
  CHECK(*chamber.read_process_value_c() == Approx(25.1));
  CHECK(*chamber.read_alarm() == true);
  REQUIRE(chamber.set_running(true).has_value());
  server.with_mapping([](modbus_mapping_t& m) { CHECK(m.tab_registers[2000] == 1); });
  auto report = chamber.bring_up();
  REQUIRE(report.has_value());
  for (const auto& c : report->checks) {
    INFO(c.name << ": " << c.detail);
    CHECK(c.ok == (c.name != "alarm"));  // identity and units match; the alarm is active
  }
}

TEST_CASE("thermistor module: every unit's T1 and T2 in few requests, errors per sensor") {
  ModbusTestServer server(0, 0, 0, 128);
  const auto cfg = json::parse(R"([
    {"serial": "FOG-0001", "gyro": {"node_id": 257, "scale_dph_per_count": 1e-4},
     "thermistors": {
       "t1": {"function": "input", "address": 0, "type": "int16", "scale": 0.01,
              "kind": "temperature", "open_circuit_raw": 32767},
       "t2": {"function": "input", "address": 1, "type": "int16", "scale": 0.01,
              "kind": "temperature", "open_circuit_raw": 32767}}},
    {"serial": "FOG-0002", "gyro": {"node_id": 258, "scale_dph_per_count": 1e-4},
     "thermistors": {
       "t1": {"function": "input", "address": 100, "type": "float32", "kind": "ntc",
              "steinhart_hart": {"a": 1.129148e-3, "b": 2.34125e-4, "c": 8.76741e-8}},
       "t2": {"function": "input", "address": 102, "type": "float32", "kind": "ntc",
              "steinhart_hart": {"a": 1.129148e-3, "b": 2.34125e-4, "c": 8.76741e-8}}}}
  ])");
  std::vector<UnitConfig> units;
  for (std::size_t i = 0; i < cfg.size(); ++i) {
    auto u = parse_unit_config(cfg[i], "units[" + std::to_string(i) + "]");
    REQUIRE(u.has_value());
    units.push_back(*u);
  }
  ThermistorModuleConfig mcfg{local(server.port())};
  mcfg.modbus.unit_id = 2;
  ThermistorModule module(mcfg, units);
  CHECK(module.request_count() == 2);  // input 0..1 and input 100..103

  server.with_mapping([](modbus_mapping_t& m) {
    m.tab_input_registers[0] = 2534;   // 25.34 degC
    m.tab_input_registers[1] = 32767;  // the module's open-circuit code
    put_float(&m.tab_input_registers[100], 10000.0f);  // 24.9997 degC (see thermistor_test)
    put_float(&m.tab_input_registers[102], 5.0e6f);    // open NTC
  });
  {
    // The daemon's way in: the same module behind the interface, from open_thermistor_source
    // (first, and closed before `module` connects: the test server serves one client at a time).
    auto source = open_thermistor_source(mcfg, units);
    REQUIRE(source);
    auto first = source->read_all();
    REQUIRE(first.has_value());
    REQUIRE(first->size() == 2);
    REQUIRE((*first)[0].t1_c.has_value());
    CHECK(*(*first)[0].t1_c == Approx(25.34));
    CHECK((*first)[0].t2_c.error().code == ErrorCode::open_circuit);
  }
  auto r = module.read_all();
  REQUIRE(r.has_value());
  REQUIRE(r->size() == 2);
  CHECK((*r)[0].serial == "FOG-0001");
  REQUIRE((*r)[0].t1_c.has_value());
  CHECK(*(*r)[0].t1_c == Approx(25.34));
  REQUIRE_FALSE((*r)[0].t2_c.has_value());
  CHECK((*r)[0].t2_c.error().code == ErrorCode::open_circuit);
  CHECK((*r)[0].t2_c.error().message.starts_with("unit FOG-0001 T2: open circuit"));
  REQUIRE((*r)[1].t1_c.has_value());
  CHECK(*(*r)[1].t1_c == Approx(24.9997).margin(1e-3));
  CHECK((*r)[1].t2_c.error().code == ErrorCode::open_circuit);

  server.stop();
  auto down = module.read_all();
  REQUIRE_FALSE(down.has_value());
  CHECK(down.error().code == ErrorCode::connection);
  CHECK(down.error().message.starts_with("thermistor module (tcp 127.0.0.1:"));
}

TEST_CASE("thermistor module: a three-axis unit's thermistors per axis, each sensor read and named by its axis", "[axis_thermistors]") {
  ModbusTestServer server(0, 0, 0, 32);
  auto channel = [](int address) {
    return json{{"function", "input"}, {"address", address}, {"type", "int16"}, {"scale", 0.01},
                {"kind", "temperature"}, {"open_circuit_raw", 32767}};
  };
  const json cfg = {{"serial", "FOG-3AX"},
                    {"gyro", {{"node_id", 257}, {"axes", 3}, {"scale_dph_per_count", 1e-4}}},
                    {"thermistors", {{"x", {{"t1", channel(0)}, {"t2", channel(1)}}},
                                     {"y", {{"t1", channel(2)}, {"t2", channel(3)}}},
                                     {"z", {{"t1", channel(20)}, {"t2", channel(21)}}}}}};
  auto unit = parse_unit_config(cfg, "units[0]");
  REQUIRE(unit.has_value());
  ThermistorModuleConfig mcfg{local(server.port())};
  mcfg.modbus.unit_id = 2;
  ThermistorModule module(mcfg, {*unit});
  CHECK(module.request_count() == 2);  // input 0..3 (x's and y's) and input 20..21 (z's)
  server.with_mapping([](modbus_mapping_t& m) {
    m.tab_input_registers[0] = 2500;   // x T1 25.00 degC
    m.tab_input_registers[1] = 2510;   // x T2
    m.tab_input_registers[2] = 2420;   // y T1
    m.tab_input_registers[3] = 2430;   // y T2
    m.tab_input_registers[20] = 2310;  // z T1
    m.tab_input_registers[21] = 32767; // z T2: open circuit
  });
  auto r = module.read_all();
  REQUIRE(r.has_value());
  REQUIRE(r->size() == 1);
  const CoilTemperatures& c = (*r)[0];
  REQUIRE(c.t1_c.has_value());
  CHECK(*c.t1_c == Approx(25.00));
  CHECK(*c.t2_c == Approx(25.10));
  REQUIRE(c.axis_t1_c.size() == 2);
  REQUIRE(c.axis_t2_c.size() == 2);
  CHECK(*c.axis_t1_c[0] == Approx(24.20));
  CHECK(*c.axis_t2_c[0] == Approx(24.30));
  CHECK(*c.axis_t1_c[1] == Approx(23.10));
  REQUIRE_FALSE(c.axis_t2_c[1].has_value());
  CHECK(c.axis_t2_c[1].error().code == ErrorCode::open_circuit);
  CHECK(c.axis_t2_c[1].error().message.starts_with("unit FOG-3AX T2z: open circuit"));
}
