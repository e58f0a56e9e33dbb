// Coil thermistor conversion: Steinhart-Hart against known NTC points, and readings that are not
// temperatures (open circuit, short, out of range) coming back as errors naming unit and sensor.
#include <catch2/catch.hpp>

#include <nlohmann/json.hpp>

#include <bit>
#include <cmath>

#include "fogbench/drivers/thermistor_conversion.hpp"

using namespace fogbench::drivers;
using nlohmann::json;

namespace {

// The coefficients published for the common 10 kOhm (at 25 degC) NTC with the R-T table
// 32650 Ohm at 0 degC and 3602 Ohm at 50 degC.
constexpr SteinhartHart ntc10k{1.129148e-3, 2.34125e-4, 8.76741e-8};

ThermistorChannelConfig ntc_channel() {
  ThermistorChannelConfig ch;
  ch.reg.function = RegisterFunction::input;
  ch.reg.type = ValueType::float32;
  ch.kind = ThermistorKind::ntc;
  ch.coefficients = ntc10k;
  return ch;  // valid 10 Ohm .. 1 MOhm, -60 .. 150 degC (the defaults)
}

std::array<std::uint16_t, 2> float_words(float f) {
  const auto u = std::bit_cast<std::uint32_t>(f);
  return {static_cast<std::uint16_t>(u >> 16), static_cast<std::uint16_t>(u)};
}

}  // namespace

TEST_CASE("Steinhart-Hart at the 10 kOhm NTC's table points") {
  // ln(10000) = 9.210340, ln^3 = 781.3166;
  // 1/T = 1.129148e-3 + 2.34125e-4 * 9.210340 + 8.76741e-8 * 781.3166
  //     = 1.129148e-3 + 2.156377e-3 + 6.85010e-5 = 3.354020e-3 1/K
  // T = 298.1497 K = 24.9997 degC. The table says 25: the fit is good to 1 mK there.
  CHECK(ntc10k.temp_c(10000.0) == Approx(24.9997).margin(1e-4));
  // ln(32650) = 10.393600: 1/T = 3.660989e-3, T = 273.1502 K = 0.0002 degC (table: 0 degC).
  CHECK(ntc10k.temp_c(32650.0) == Approx(0.0002).margin(1e-4));
  // ln(3602) = 8.189245: 1/T = 3.094606e-3, T = 323.1430 K = 49.9930 degC (table: 50 degC).
  CHECK(ntc10k.temp_c(3602.0) == Approx(49.9930).margin(1e-4));
}

TEST_CASE("Steinhart-Hart with c = 0 is the beta equation, exactly") {
  // 1/T = 1/T0 + ln(R/R0)/beta is Steinhart-Hart with a = 1/T0 - ln(R0)/beta, b = 1/beta, c = 0.
  const double beta = 3950.0, r0 = 10000.0, t0 = 298.15;
  const SteinhartHart sh{1.0 / t0 - std::log(r0) / beta, 1.0 / beta, 0.0};
  CHECK(sh.temp_c(r0) == Approx(25.0).margin(1e-9));
  // At 0 degC: R = R0 exp(beta (1/273.15 - 1/298.15)) = 10000 exp(1.212556) = 33620.6 Ohm.
  const double r_0c = r0 * std::exp(beta * (1.0 / 273.15 - 1.0 / t0));
  CHECK(r_0c == Approx(33620.6).margin(0.1));
  CHECK(sh.temp_c(r_0c) == Approx(0.0).margin(1e-9));
}

TEST_CASE("an NTC resistance converts to a temperature") {
  const auto w = float_words(10000.0f);
  auto t = convert_thermistor(ntc_channel(), w, "unit FOG-0001 T1");
  REQUIRE(t.has_value());
  CHECK(*t == Approx(24.9997).margin(1e-4));
}

TEST_CASE("an open NTC is an open_circuit error naming unit and sensor") {
  const auto w = float_words(2.0e6f);  // above the 1 MOhm limit
  auto t = convert_thermistor(ntc_channel(), w, "unit FOG-0002 T2");
  REQUIRE_FALSE(t.has_value());
  CHECK(t.error().code == ErrorCode::open_circuit);
  CHECK(t.error().message == "unit FOG-0002 T2: open circuit (resistance 2000000 ohm, limit 1000000 ohm)");
}

TEST_CASE("a shorted NTC is out_of_range") {
  const auto w = float_words(5.0f);
  auto t = convert_thermistor(ntc_channel(), w, "unit FOG-0002 T1");
  REQUIRE_FALSE(t.has_value());
  CHECK(t.error().code == ErrorCode::out_of_range);
  CHECK(t.error().message.starts_with("unit FOG-0002 T1: short circuit"));
}

TEST_CASE("a scaled temperature register, its open-circuit code and its range") {
  ThermistorChannelConfig ch;
  ch.reg.function = RegisterFunction::input;
  ch.reg.type = ValueType::int16;
  ch.reg.scale = 0.01;
  ch.kind = ThermistorKind::temperature;
  ch.open_circuit_raw = 32767;
  const std::uint16_t ok[] = {2534};  // 25.34 degC
  CHECK(*convert_thermistor(ch, ok, "unit A T1") == Approx(25.34));
  const std::uint16_t cold[] = {0xF830};  // -2000 -> -20.00 degC
  CHECK(*convert_thermistor(ch, cold, "unit A T1") == Approx(-20.0));
  const std::uint16_t open[] = {32767};
  auto o = convert_thermistor(ch, open, "unit A T2");
  REQUIRE_FALSE(o.has_value());
  CHECK(o.error().code == ErrorCode::open_circuit);
  CHECK(o.error().message == "unit A T2: open circuit (module reports 32767)");
  const std::uint16_t hot[] = {20000};  // 200 degC, above the 150 degC limit
  auto h = convert_thermistor(ch, hot, "unit A T1");
  REQUIRE_FALSE(h.has_value());
  CHECK(h.error().code == ErrorCode::out_of_range);
  CHECK(h.error().message == "unit A T1: 200 degC outside -60..150 degC");
}

TEST_CASE("thermistor channel configuration") {
  auto ok = parse_thermistor_channel(json::parse(R"({
      "function": "input", "address": 4, "type": "float32", "word_order": "low_first",
      "kind": "ntc", "steinhart_hart": {"a": 1.129148e-3, "b": 2.34125e-4, "c": 8.76741e-8},
      "valid_ohm": {"min": 50, "max": 2e6}, "valid_c": {"min": -70, "max": 130}})"),
                                     "units[0].thermistors.t1");
  REQUIRE(ok.has_value());
  CHECK(ok->kind == ThermistorKind::ntc);
  CHECK(ok->reg.word_order == WordOrder::low_first);
  CHECK(ok->max_ohm == 2e6);
  CHECK(ok->min_c == -70);

  const std::string p = "units[0].thermistors.t2";
  auto err = [&](const char* text) {
    auto r = parse_thermistor_channel(json::parse(text), p);
    REQUIRE_FALSE(r.has_value());
    return r.error().message;
  };
  CHECK(err(R"({"function": "input", "address": 0, "type": "int16"})") ==
        "units[0].thermistors.t2.kind: missing (expected a string)");
  CHECK(err(R"({"function": "input", "address": 0, "type": "int16", "kind": "ptc"})") ==
        "units[0].thermistors.t2.kind: unknown kind 'ptc' (expected temperature, ntc)");
  CHECK(err(R"({"function": "input", "address": 0, "type": "float32", "kind": "ntc"})")
            .starts_with("units[0].thermistors.t2.steinhart_hart: missing"));
  CHECK(err(R"({"function": "input", "address": 0, "type": "float32", "kind": "ntc",
                "steinhart_hart": {"a": 1e-3, "b": 0, "c": 0}})") ==
        "units[0].thermistors.t2.steinhart_hart.b: must be positive for an NTC");
  CHECK(err(R"({"function": "coil", "address": 0, "kind": "temperature"})")
            .starts_with("units[0].thermistors.t2.function: 'coil' holds bits"));
  CHECK(err(R"({"function": "input", "address": 0, "type": "int16", "kind": "temperature",
                "valid_c": {"min": 10, "max": 0}})") ==
        "units[0].thermistors.t2.valid_c: min (10) must be below max (0)");
}
