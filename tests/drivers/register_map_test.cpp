// Register maps: validation messages naming the field, the shipped maps, and the conversions
// between register words and values for every type and word order.
#include <catch2/catch.hpp>

#include <nlohmann/json.hpp>

#include "fogbench/drivers/register_map.hpp"

using namespace fogbench::drivers;
using nlohmann::json;

namespace {

// A valid map; each validation case breaks one thing in it.
json valid_map() {
  return json::parse(R"({
    "name": "test",
    "registers": {
      "setpoint":      {"function": "holding",  "address": 0, "type": "float32"},
      "process_value": {"function": "input",    "address": 0, "type": "float32"},
      "status":        {"function": "input",    "address": 2, "type": "uint16", "bits": {"heating": 0}},
      "run":           {"function": "coil",     "address": 0},
      "alarm":         {"function": "discrete", "address": 0}
    }
  })");
}

std::string error_of(const json& j) {
  auto r = parse_register_map(j);
  REQUIRE_FALSE(r.has_value());
  CHECK(r.error().code == ErrorCode::config);
  return r.error().message;
}

RegisterSpec spec(ValueType type, WordOrder order = WordOrder::high_first, double scale = 1.0,
                  double offset = 0.0) {
  RegisterSpec s;
  s.function = RegisterFunction::holding;
  s.address = 10;
  s.type = type;
  s.word_order = order;
  s.scale = scale;
  s.offset = offset;
  return s;
}

}  // namespace

TEST_CASE("a valid map parses") {
  auto m = parse_register_map(valid_map());
  REQUIRE(m.has_value());
  CHECK(m->setpoint.type == ValueType::float32);
  CHECK(m->setpoint.width() == 2);
  CHECK(m->run.reg.function == RegisterFunction::coil);
  REQUIRE(m->status.has_value());
  CHECK(m->status->bits.size() == 1);
  CHECK_FALSE(m->identity.has_value());
}

TEST_CASE("map validation: an unknown type names the field and the accepted types") {
  json j = valid_map();
  j["registers"]["setpoint"]["type"] = "int24";
  CHECK(error_of(j) ==
        "registers.setpoint.type: unknown type 'int24' (expected int16, uint16, int32, uint32, float32)");
}

TEST_CASE("map validation: overlapping registers in one table") {
  json j = valid_map();
  // process_value is input 0..1 (float32); status at input 1 shares register 1.
  j["registers"]["status"]["address"] = 1;
  CHECK(error_of(j) ==
        "registers.status.address: input 1 (uint16) overlaps registers.process_value "
        "(input 0..1 (float32, high_first))");
}

TEST_CASE("map validation: the same address in different tables is not an overlap") {
  json j = valid_map();  // holding 0, input 0, coil 0 and discrete 0 all coexist
  CHECK(parse_register_map(j).has_value());
}

TEST_CASE("map validation: a missing required register") {
  json j = valid_map();
  j["registers"].erase("alarm");
  CHECK(error_of(j) == "registers.alarm: missing (required: setpoint, process_value, run, alarm)");
}

TEST_CASE("map validation: a written register in a read-only table") {
  json j = valid_map();
  j["registers"]["setpoint"]["function"] = "input";
  CHECK(error_of(j) ==
        "registers.setpoint.function: 'input' cannot be written; setpoint is written (expected holding)");
  j = valid_map();
  j["registers"]["run"]["function"] = "discrete";
  CHECK(error_of(j) ==
        "registers.run.function: 'discrete' cannot be written; run is written (expected coil or holding)");
}

TEST_CASE("map validation: other refusals name their field") {
  json j = valid_map();
  j["registers"]["setpoint"]["scael"] = 2;
  CHECK(error_of(j) == "registers.setpoint.scael: unknown field (known: function, address, type, word_order, scale, offset, description)");

  j = valid_map();
  j["registers"]["humidity"] = {{"function", "input"}, {"address", 9}, {"type", "uint16"}};
  CHECK(error_of(j).starts_with("registers.humidity: unknown register"));

  j = valid_map();
  j["registers"]["process_value"]["function"] = "analog";
  CHECK(error_of(j).starts_with("registers.process_value.function: unknown function 'analog'"));

  j = valid_map();
  j["registers"]["process_value"].erase("type");
  CHECK(error_of(j).starts_with("registers.process_value.type: missing"));

  j = valid_map();  // a float32 at 65535 would need register 65536
  j["registers"]["process_value"]["address"] = 65535;
  CHECK(error_of(j) == "registers.process_value.address: expected an integer 0..65534 (got 65535)");

  j = valid_map();
  j["registers"]["process_value"]["scale"] = 0;
  CHECK(error_of(j) == "registers.process_value.scale: must not be 0");

  j = valid_map();
  j["registers"]["alarm"]["mask"] = 1;
  CHECK(error_of(j) == "registers.alarm.mask: only for a register (a bit is its own alarm)");

  j = valid_map();
  j["registers"]["status"]["bits"]["door"] = 16;  // a uint16 has bits 0..15
  CHECK(error_of(j) == "registers.status.bits.door: expected an integer 0..15 (got 16)");

  j = valid_map();
  j["registers"]["run"]["type"] = "uint16";
  CHECK(error_of(j).starts_with("registers.run.type: 'uint16' on a coil"));

  j = valid_map();
  j["registers"]["setpoint"]["word_order"] = "middle";
  CHECK(error_of(j).starts_with("registers.setpoint.word_order: unknown word order 'middle'"));
}

TEST_CASE("a map embedded in a configuration prefixes its path") {
  auto r = parse_register_map(json::array(), "chamber.map");
  REQUIRE_FALSE(r.has_value());
  CHECK(r.error().message == "chamber.map: expected an object (got an array)");
}

TEST_CASE("the shipped maps load and validate") {
  const std::string dir = FOGBENCH_SOURCE_DIR "/drivers/maps/";
  auto mock = load_register_map(dir + "mock.json");
  REQUIRE(mock.has_value());
  CHECK(mock->setpoint.function == RegisterFunction::holding);
  CHECK(mock->setpoint.address == 0);
  CHECK(mock->process_value.function == RegisterFunction::input);
  REQUIRE(mock->identity.has_value());
  CHECK(mock->identity->expect == 0xF0B2u);

  auto f4 = load_register_map(dir + "watlow-f4.json");
  REQUIRE(f4.has_value());
  CHECK(f4->setpoint.address == 300);
  CHECK(f4->setpoint.type == ValueType::int16);
  CHECK(f4->process_value.address == 100);
  CHECK(f4->run.reg.function == RegisterFunction::holding);
  REQUIRE(f4->identity.has_value());
  CHECK(f4->identity->expect == 5270u);

  auto missing = load_register_map(dir + "no-such-map.json");
  REQUIRE_FALSE(missing.has_value());
  CHECK(missing.error().code == ErrorCode::config);
}

TEST_CASE("int16: two's complement, scale and offset") {
  const std::uint16_t w[] = {0xFF38};  // -200
  CHECK(*decode_value(spec(ValueType::int16, WordOrder::high_first, 0.1), w) == Approx(-20.0));
  // raw 1000 * 0.1 - 40 = 60 (a unit conversion done by offset).
  const std::uint16_t w2[] = {1000};
  CHECK(*decode_value(spec(ValueType::int16, WordOrder::high_first, 0.1, -40.0), w2) == Approx(60.0));
  auto e = encode_value(spec(ValueType::int16, WordOrder::high_first, 0.1), -20.0);
  REQUIRE(e.has_value());
  CHECK((*e)[0] == 0xFF38);
  // 21.04 / 0.1 = 210.4 rounds to 210 = 0x00D2.
  CHECK((*encode_value(spec(ValueType::int16, WordOrder::high_first, 0.1), 21.04))[0] == 0x00D2);
}

TEST_CASE("uint16: the full range") {
  const std::uint16_t w[] = {0xFFFF};
  CHECK(*decode_value(spec(ValueType::uint16, WordOrder::high_first, 0.01), w) == Approx(655.35));
  CHECK((*encode_value(spec(ValueType::uint16), 65535))[0] == 0xFFFF);
}

TEST_CASE("int32 in both word orders") {
  // -100000 = 0xFFFE7960: high word 0xFFFE, low word 0x7960.
  const std::uint16_t hi_first[] = {0xFFFE, 0x7960};
  const std::uint16_t lo_first[] = {0x7960, 0xFFFE};
  CHECK(*decode_value(spec(ValueType::int32, WordOrder::high_first, 0.001), hi_first) == Approx(-100.0));
  CHECK(*decode_value(spec(ValueType::int32, WordOrder::low_first, 0.001), lo_first) == Approx(-100.0));
  auto e = encode_value(spec(ValueType::int32, WordOrder::low_first, 0.001), -100.0);
  REQUIRE(e.has_value());
  CHECK((*e)[0] == 0x7960);
  CHECK((*e)[1] == 0xFFFE);
}

TEST_CASE("uint32 above 2^31") {
  // 3,000,000,000 = 0xB2D05E00.
  const std::uint16_t w[] = {0xB2D0, 0x5E00};
  CHECK(*decode_value(spec(ValueType::uint32), w) == 3.0e9);
  auto e = encode_value(spec(ValueType::uint32, WordOrder::high_first), 3.0e9);
  REQUIRE(e.has_value());
  CHECK((*e)[0] == 0xB2D0);
  CHECK((*e)[1] == 0x5E00);
  CHECK(raw_unsigned(spec(ValueType::uint32), w) == 0xB2D05E00u);
}

TEST_CASE("float32 in both word orders") {
  // 25.5f = 0x41CC0000 (sign 0, exponent 131, mantissa 0x4C0000).
  const std::uint16_t hi_first[] = {0x41CC, 0x0000};
  const std::uint16_t lo_first[] = {0x0000, 0x41CC};
  CHECK(*decode_value(spec(ValueType::float32, WordOrder::high_first), hi_first) == 25.5);
  CHECK(*decode_value(spec(ValueType::float32, WordOrder::low_first), lo_first) == 25.5);
  auto e = encode_value(spec(ValueType::float32, WordOrder::low_first), 25.5);
  REQUIRE(e.has_value());
  CHECK((*e)[0] == 0x0000);
  CHECK((*e)[1] == 0x41CC);
  // A quiet NaN (0x7FC00000) is not a temperature.
  const std::uint16_t nan[] = {0x7FC0, 0x0000};
  auto d = decode_value(spec(ValueType::float32), nan);
  REQUIRE_FALSE(d.has_value());
  CHECK(d.error().code == ErrorCode::corrupt);
}

TEST_CASE("values that do not fit their type are refused, not wrapped") {
  // int16 with scale 0.1 holds -3276.8..3276.7.
  auto s = spec(ValueType::int16, WordOrder::high_first, 0.1);
  CHECK(encode_value(s, -3276.8).has_value());
  auto over = encode_value(s, 3276.8);
  REQUIRE_FALSE(over.has_value());
  CHECK(over.error().code == ErrorCode::out_of_range);
  CHECK_FALSE(encode_value(spec(ValueType::uint16), -1).has_value());
  CHECK_FALSE(encode_value(spec(ValueType::uint32), 4294967296.0).has_value());
  CHECK_FALSE(encode_value(spec(ValueType::float32), 1e39).has_value());
  CHECK_FALSE(encode_value(spec(ValueType::float32), std::nan("")).has_value());
}
