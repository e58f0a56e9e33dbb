// Parsing of the drivers' configuration: the shipped example, and refusals naming the field.
#include <catch2/catch.hpp>

#include <nlohmann/json.hpp>

#include <fstream>

#include "fogbench/drivers/config.hpp"

using namespace fogbench::drivers;
using nlohmann::json;

namespace {

const std::filesystem::path map_dir = FOGBENCH_SOURCE_DIR "/drivers/maps";

json example() {
  std::ifstream in(FOGBENCH_SOURCE_DIR "/drivers/examples/mock-bench.json");
  REQUIRE(in);
  return json::parse(in);
}

std::string error_of(const json& j) {
  auto r = parse_drivers_config(j, map_dir);
  REQUIRE_FALSE(r.has_value());
  CHECK(r.error().code == ErrorCode::config);
  return r.error().message;
}

}  // namespace

TEST_CASE("the example configuration of the mock bench parses") {
  auto cfg = parse_drivers_config(example(), map_dir);
  REQUIRE(cfg.has_value());
  CHECK(cfg->chamber.modbus.transport == ModbusEndpoint::Transport::tcp);
  CHECK(cfg->chamber.modbus.port == 1502);
  CHECK(cfg->chamber.modbus.response_timeout_ms == 500);
  CHECK(cfg->chamber.map.name == "fogbench mock chamber");
  CHECK(cfg->chamber.map_file == (map_dir / "mock.json").string());
  CHECK(cfg->chamber.setpoint_limits_c.max_c == 150);
  CHECK(cfg->thermistors.modbus.unit_id == 2);
  CHECK(cfg->gyro_bus.transport == "unix:/tmp/fogbench-mock-can.sock");
  REQUIRE(cfg->units.size() == 2);
  CHECK(cfg->units[0].serial == "FOG-0001");
  CHECK(cfg->units[0].gyro.node_id == 257);
  CHECK(cfg->units[0].gyro.scale_dph_per_count == 0.001);
  CHECK(cfg->units[1].gyro.mode == GyroMode::increment);
  CHECK(cfg->units[1].gyro.frame_rate_hz == 8000);
  CHECK(cfg->units[1].t2.kind == ThermistorKind::ntc);
  CHECK(cfg->units[1].t2.reg.address == 102);
}

TEST_CASE("a node id out of range names the unit and field") {
  json j = example();
  j["units"][1]["gyro"]["node_id"] = 4096;
  CHECK(error_of(j) == "units[1].gyro.node_id: expected an integer 1..2047 (got 4096)");
  j["units"][1]["gyro"]["node_id"] = "0x102";
  CHECK(error_of(j) == "units[1].gyro.node_id: expected an integer 1..2047 (got a string)");
}

TEST_CASE("units must not share a node id, a serial or a thermistor register") {
  json j = example();
  j["units"][1]["gyro"]["node_id"] = 257;
  CHECK(error_of(j) == "units[1].gyro.node_id: 257 is already used by units[0]");

  j = example();
  j["units"][1]["serial"] = "FOG-0001";
  CHECK(error_of(j) == "units[1].serial: 'FOG-0001' is already used by units[0]");

  j = example();
  j["units"][1]["thermistors"]["t1"]["address"] = 0;  // a float32 at input 0..1 over unit 0's T1, T2
  CHECK(error_of(j) ==
        "units[1].thermistors.t1.address: input 0..1 (float32, high_first) overlaps "
        "units[0].thermistors.t1 (input 0 (int16))");
}

TEST_CASE("units are bench slots: named by index unless configured, the serial only a default") {
  json j = example();
  auto cfg = parse_drivers_config(j, map_dir);
  REQUIRE(cfg);
  CHECK(cfg->units[0].slot == "A");  // no "slot" in the example: named by index
  CHECK(cfg->units[1].slot == "B");
  CHECK(cfg->units[1].serial == "FOG-0002");  // an old configuration keeps its serials as defaults

  j["units"][0]["slot"] = "left-1";
  j["units"][1].erase("serial");
  cfg = parse_drivers_config(j, map_dir);
  REQUIRE(cfg);
  CHECK(cfg->units[0].slot == "left-1");
  CHECK(cfg->units[1].slot == "B");
  CHECK(cfg->units[1].serial.empty());  // no default: the serial is given per run

  CHECK(default_slot_name(25) == "Z");
  CHECK(default_slot_name(26) == "AA");
  CHECK(default_slot_name(27) == "AB");
}

TEST_CASE("a bad or repeated slot name names the key") {
  json j = example();
  j["units"][0]["slot"] = "B";  // units[1] is named B by its index
  CHECK(error_of(j) == "units[1].slot: 'B' is already the slot of units[0] (named by its index)");
  j["units"][1]["slot"] = "B";
  CHECK(error_of(j) == "units[1].slot: 'B' is already the slot of units[0]");

  j = example();
  j["units"][1]["slot"] = "";
  CHECK(error_of(j) == "units[1].slot: must not be empty");
  j["units"][1]["slot"] = "A 2";
  CHECK(error_of(j) == "units[1].slot: 'A 2': only letters, digits, '_' and '-'");
  j["units"][1]["slot"] = std::string(17, 'x');
  CHECK(error_of(j) == "units[1].slot: longer than 16 characters (17)");
  j["units"][1]["slot"] = 2;
  CHECK(error_of(j).starts_with("units[1].slot: expected a string"));

  j = example();
  j["units"][1]["serial"] = "";
  CHECK(error_of(j) == "units[1].serial: must not be empty (leave it out for no default)");
  j["units"][0].erase("serial");
  j["units"][1].erase("serial");  // two slots without a default serial do not clash
  CHECK(parse_drivers_config(j, map_dir).has_value());
}

TEST_CASE("gyro mode fields") {
  json j = example();
  j["units"][1]["gyro"].erase("frame_rate_hz");
  CHECK(error_of(j) == "units[1].gyro.frame_rate_hz: missing (expected a number)");
  j = example();
  j["units"][0]["gyro"]["mode"] = "angle";
  CHECK(error_of(j) == "units[0].gyro.mode: unknown mode 'angle' (expected rate, increment)");
  j = example();
  j["units"][0]["gyro"]["frame_rate_hz"] = 100;
  CHECK(error_of(j) == "units[0].gyro.frame_rate_hz: not used in mode 'rate'");
}

TEST_CASE("modbus endpoint fields") {
  json j = example();
  j["chamber"]["modbus"]["transport"] = "udp";
  CHECK(error_of(j) == "chamber.modbus.transport: unknown transport 'udp' (expected tcp, rtu)");
  j = example();
  j["chamber"]["modbus"]["unit_id"] = 0;
  CHECK(error_of(j) == "chamber.modbus.unit_id: expected an integer 1..247 (got 0)");
  j = example();
  j["thermistors"]["modbus"]["backoff"] = {{"initial_ms", 1000}, {"max_ms", 10}};
  CHECK(error_of(j) == "thermistors.modbus.backoff.max_ms: must be at least initial_ms (1000)");

  auto rtu = parse_modbus_endpoint(json::parse(R"({"transport": "rtu", "device": "/dev/ttyUSB0",
      "baud": 9600, "parity": "even", "stop_bits": 1, "unit_id": 3})"), "chamber.modbus");
  REQUIRE(rtu.has_value());
  CHECK(rtu->parity == 'E');
  CHECK(rtu->describe() == "rtu /dev/ttyUSB0 9600 8E1 unit 3");
  auto mixed = parse_modbus_endpoint(json::parse(R"({"transport": "rtu", "device": "/dev/ttyS0",
      "host": "10.0.0.1"})"), "chamber.modbus");
  REQUIRE_FALSE(mixed.has_value());
  CHECK(mixed.error().message == "chamber.modbus.host: only for transport 'tcp'");
}

TEST_CASE("chamber map by file or inline, with errors under chamber.map") {
  json j = example();
  j["chamber"]["map"] = "no-such.json";
  CHECK(error_of(j).starts_with("chamber.map: "));

  j = example();
  j["chamber"]["map"] = json::parse(R"({"registers": {
      "setpoint": {"function": "holding", "address": 0, "type": "int24"}}})");
  // Presence is checked before types: the first missing register is named.
  CHECK(error_of(j) ==
        "chamber.map.registers.process_value: missing (required: setpoint, process_value, run, alarm)");
  // With every required register present, the type error surfaces with its full path.
  j["chamber"]["map"] = json::parse(R"({"registers": {
      "setpoint": {"function": "holding", "address": 0, "type": "int24"},
      "process_value": {"function": "input", "address": 0, "type": "int16"},
      "run": {"function": "coil", "address": 0},
      "alarm": {"function": "discrete", "address": 0}}})");
  CHECK(error_of(j) ==
        "chamber.map.registers.setpoint.type: unknown type 'int24' (expected int16, uint16, int32, "
        "uint32, float32)");

  j = example();
  j["chamber"]["setpoint_limits_c"] = {{"min", 100}, {"max", -10}};
  CHECK(error_of(j) == "chamber.setpoint_limits_c: min (100) must be below max (-10)");
}

TEST_CASE("top-level sections") {
  json j = example();
  j.erase("gyro_bus");
  CHECK(error_of(j) == "gyro_bus: missing");
  j = example();
  j["units"] = json::array();
  CHECK(error_of(j) == "units: expected a non-empty array");
  j = example();
  j["chamberr"] = 1;
  CHECK(error_of(j).starts_with("chamberr: unknown field"));
}

TEST_CASE("a gyro's startup_flag: true unless configured false, anything else named") {
  json j = example();
  auto cfg = parse_drivers_config(j, map_dir);
  REQUIRE(cfg.has_value());
  CHECK(cfg->units[0].gyro.startup_flag);
  j["units"][0]["gyro"]["startup_flag"] = false;
  cfg = parse_drivers_config(j, map_dir);
  REQUIRE(cfg.has_value());
  CHECK_FALSE(cfg->units[0].gyro.startup_flag);
  CHECK(cfg->units[1].gyro.startup_flag);
  j["units"][0]["gyro"]["startup_flag"] = "no";
  CHECK(error_of(j).starts_with("units[0].gyro.startup_flag: expected true or false"));
}

TEST_CASE("a serial gyro bus: frame by file or inline, refused where it does not belong", "[serial]") {
  const std::filesystem::path examples = FOGBENCH_SOURCE_DIR "/drivers/examples";
  json j = example();
  j["units"].erase(1);  // a serial line carries one gyro
  j["gyro_bus"] = {{"transport", "serial:/dev/ttyUSB0?baud=921600"}, {"frame", (examples / "kvh-1775-format-a.json").string()}};
  auto cfg = parse_drivers_config(j, map_dir);
  REQUIRE(cfg.has_value());
  REQUIRE(cfg->gyro_bus.frame.has_value());
  CHECK(cfg->gyro_bus.frame->length == 36);
  CHECK(cfg->gyro_bus.frame_file == (examples / "kvh-1775-format-a.json").string());

  std::ifstream in(examples / "kvh-1775-format-a.json");
  j["gyro_bus"]["frame"] = json::parse(in);
  REQUIRE(parse_drivers_config(j, map_dir).has_value());
  j["gyro_bus"]["frame"]["crc"]["kind"] = "crc7";
  CHECK(error_of(j).starts_with("gyro_bus.frame.crc.kind: unknown CRC 'crc7'"));

  j["gyro_bus"].erase("frame");
  CHECK(error_of(j).starts_with("gyro_bus.frame: missing"));
  j["gyro_bus"]["frame"] = "no-such-frame.json";
  CHECK(error_of(j).starts_with("gyro_bus.frame: cannot open"));

  j["gyro_bus"]["frame"] = (examples / "kvh-1775-format-a.json").string();
  j["gyro_bus"]["transport"] = "serial:/dev/ttyUSB0?baud=921600&framing=8O2";
  REQUIRE(parse_drivers_config(j, map_dir).has_value());
  j["gyro_bus"]["transport"] = "serial:/dev/ttyUSB0?framing=8X1";
  CHECK(error_of(j).starts_with("gyro_bus.transport: framing: '8X1': parity 'X' is not N (none), E (even) or O (odd)"));
  // The KVH's sync word 0xFE81FF55 cannot cross a 7-bit line.
  j["gyro_bus"]["transport"] = "serial:/dev/ttyUSB0?framing=7E1";
  CHECK(error_of(j).starts_with("gyro_bus.transport: framing 7E1: 7 data bits cannot carry the frame's sync word"));

  json can = example();
  can["gyro_bus"]["frame"] = (examples / "kvh-1775-format-a.json").string();
  CHECK(error_of(can) == "gyro_bus.frame: only a serial: transport has a frame layout");

  json two = example();
  two["gyro_bus"] = {{"transport", "serial:/dev/ttyUSB0"}, {"frame", (examples / "kvh-1775-format-a.json").string()}};
  auto r = parse_drivers_config(two, map_dir);
  REQUIRE_FALSE(r.has_value());
  CHECK(r.error().message.starts_with("gyro_bus.transport: a serial line carries one gyro's frames, but there are 2 units"));

  json inc = example();
  inc["units"].erase(0);  // the increment-mode unit remains
  inc["gyro_bus"] = two["gyro_bus"];
  r = parse_drivers_config(inc, map_dir);
  REQUIRE_FALSE(r.has_value());
  CHECK(r.error().message.starts_with("units[0].gyro.mode:"));
}

TEST_CASE("units on serial lines of their own beside the CAN bus: gyro_line parsed and refused by field", "[serial]") {
  const std::string kvh = FOGBENCH_SOURCE_DIR "/drivers/examples/kvh-1775-format-a.json";
  json j = example();  // two units on gyro_bus.transport (unix:), the second in increment mode
  j["units"][0]["gyro_line"] = {{"transport", "serial:/dev/ttyUSB0?baud=921600&framing=8N1"}, {"frame", kvh}};
  auto cfg = parse_drivers_config(j, map_dir);
  REQUIRE(cfg.has_value());
  REQUIRE(cfg->gyro_bus.lines.size() == 1);
  const auto& line = cfg->gyro_bus.lines[0];
  CHECK(line.node_id == cfg->units[0].gyro.node_id);
  CHECK(line.transport == "serial:/dev/ttyUSB0?baud=921600&framing=8N1");
  CHECK(line.frame.length == 36);
  CHECK(line.frame_file == kvh);
  CHECK(line.key == "units[0].gyro_line");
  CHECK(cfg->gyro_bus.transport.starts_with("unix:"));
  CHECK_FALSE(cfg->gyro_bus.frame.has_value());

  // Every unit on a line: gyro_bus.transport may be left out.
  json all = j;
  all["units"].erase(1);
  all["gyro_bus"].erase("transport");
  cfg = parse_drivers_config(all, map_dir);
  REQUIRE(cfg.has_value());
  CHECK(cfg->gyro_bus.transport.empty());
  json none = j;
  none["gyro_bus"].erase("transport");
  CHECK(error_of(none) == "gyro_bus.transport: missing (units[1] has no gyro_line: it is read on the bus)");

  json bad = j;
  bad["units"][0]["gyro_line"]["transport"] = "can:can1";
  CHECK(error_of(bad).starts_with("units[0].gyro_line.transport: expected serial:DEVICE"));
  bad = j;
  bad["units"][0]["gyro_line"]["transport"] = "serial:/dev/ttyUSB0?framing=8Q1";
  CHECK(error_of(bad).starts_with("units[0].gyro_line.transport: framing: '8Q1': parity 'Q' is not N"));
  bad = j;
  bad["units"][0]["gyro_line"]["transport"] = "serial:/dev/ttyUSB0?framing=7E1";
  CHECK(error_of(bad).starts_with("units[0].gyro_line.transport: framing 7E1: 7 data bits cannot carry"));
  bad = j;
  bad["units"][0]["gyro_line"].erase("frame");
  CHECK(error_of(bad).starts_with("units[0].gyro_line.frame: missing"));
  bad = j;
  bad["units"][0]["gyro_line"]["frame"] = "no-such-frame.json";
  CHECK(error_of(bad).starts_with("units[0].gyro_line.frame: cannot open"));
  bad = j;
  bad["units"][0]["gyro_line"]["baud"] = 9600;
  CHECK(error_of(bad).starts_with("units[0].gyro_line.baud: unknown field"));
  bad = j;
  bad["units"][1]["gyro_line"] = j["units"][0]["gyro_line"];  // unit 1 is in increment mode
  CHECK(error_of(bad).starts_with("units[1].gyro.mode: a serial gyro's frames carry a rate"));
  bad["units"][1]["gyro"] = j["units"][0]["gyro"];
  bad["units"][1]["gyro"]["node_id"] = 300;
  CHECK(error_of(bad) == "units[1].gyro_line.transport: device '/dev/ttyUSB0' is already the line of units[0].gyro_line");
  bad["units"][1]["gyro_line"]["transport"] = "serial:/dev/ttyUSB1";
  REQUIRE(parse_drivers_config(bad, map_dir).has_value());  // two serial gyros and no CAN unit left
  CHECK(parse_drivers_config(bad, map_dir)->gyro_bus.lines.size() == 2);
  bad = j;
  bad["units"].erase(1);
  bad["gyro_bus"] = {{"transport", "serial:/dev/ttyUSB7"}, {"frame", kvh}};
  CHECK(error_of(bad).starts_with("units[0].gyro_line: gyro_bus.transport is already a serial line"));
}
