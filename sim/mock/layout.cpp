// The served layout: default units, the chamber map, the drivers configuration, and the
// encoding of thermistor readings into module registers. See layout.hpp.
#include "layout.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdio>
#include <fstream>

namespace fogbench::mock {

using nlohmann::json;

namespace {

// The NTC of drivers/examples/mock-bench.json: a common 10 kohm (at 25 degC) thermistor.
const json ntc_coefficients = {{"a", 1.129148e-3}, {"b", 2.34125e-4}, {"c", 8.76741e-8}};

std::expected<drivers::ThermistorChannelConfig, std::string> parse_channel(const json& j,
                                                                          const std::string& path) {
  auto ch = drivers::parse_thermistor_channel(j, path);
  if (!ch) return std::unexpected(ch.error().message);
  return *ch;
}

}  // namespace

std::expected<UnitLayout, std::string> default_unit_layout(std::size_t i, int frame_rate_hz, int axes, bool axis_thermistors) {
  if (axes != 1 && axes != 3) return std::unexpected("axes must be 1 or 3 (got " + std::to_string(axes) + ")");
  if (axis_thermistors && axes != 3) return std::unexpected(std::string("thermistors per axis need three axes"));
  if (i >= max_units) return std::unexpected("at most " + std::to_string(max_units) + " units");
  if (frame_rate_hz < 1 || frame_rate_hz > max_frame_rate_hz) {
    return std::unexpected("frame rate must be 1.." + std::to_string(max_frame_rate_hz) + " Hz");
  }
  UnitLayout u;
  char serial[16];
  std::snprintf(serial, sizeof serial, "SIM-%04zu", i + 1);
  u.serial = serial;
  u.frame_rate_hz = frame_rate_hz;
  u.gyro.node_id = static_cast<std::uint16_t>(axes == 1 ? 257 + i : 257 + 4 * i);
  u.gyro.axes = static_cast<std::uint8_t>(axes);
  u.axis_bias_dph.assign(static_cast<std::size_t>(axes), 0.0);
  const auto a = static_cast<int>(i);
  if (i % 2 == 0) {
    u.gyro.mode = drivers::GyroMode::rate;
    u.gyro.scale_dph_per_count = default_rate_scale_dph_per_count;
    auto channel = [](int address) {
      return json{{"function", "input"}, {"address", address}, {"type", "int16"}, {"scale", 0.01},
                  {"kind", "temperature"}, {"open_circuit_raw", 32767}};
    };
    u.t1_json = channel(a);
    u.t2_json = channel(a + 1);
    if (axis_thermistors) u.axis_json = {{channel(200 + a), channel(201 + a)}, {channel(264 + a), channel(265 + a)}};
  } else {
    u.gyro.mode = drivers::GyroMode::increment;
    u.gyro.scale_deg_per_count = 1e-7;
    u.gyro.frame_rate_hz = 8000;  // nominal, as the example declares: see counts_per_dph()
    auto channel = [](int address) {
      return json{{"function", "input"}, {"address", address}, {"type", "float32"},
                  {"word_order", "high_first"}, {"kind", "ntc"}, {"steinhart_hart", ntc_coefficients},
                  {"valid_ohm", {{"min", 50}, {"max", 2000000}}}};
    };
    u.t1_json = channel(100 + 2 * (a - 1));
    u.t2_json = channel(102 + 2 * (a - 1));
    if (axis_thermistors) {
      u.axis_json = {{channel(400 + 2 * (a - 1)), channel(402 + 2 * (a - 1))},
                     {channel(500 + 2 * (a - 1)), channel(502 + 2 * (a - 1))}};
    }
  }
  auto t1 = parse_channel(u.t1_json, "t1");
  if (!t1) return std::unexpected(t1.error());
  auto t2 = parse_channel(u.t2_json, "t2");
  if (!t2) return std::unexpected(t2.error());
  u.t1 = *t1;
  u.t2 = *t2;
  for (std::size_t k = 0; k < u.axis_json.size(); ++k) {
    std::array<drivers::ThermistorChannelConfig, 2> pair;
    for (std::size_t s = 0; s < 2; ++s) {
      auto ch = parse_channel(u.axis_json[k][s], std::string(k == 0 ? "y." : "z.") + (s == 0 ? "t1" : "t2"));
      if (!ch) return std::unexpected(ch.error());
      pair[s] = *ch;
    }
    u.axis_thermistors.push_back(pair);
  }
  return u;
}

std::expected<ServedMap, std::string> load_served_map(const std::string& file) {
  ServedMap served;
  try {
    if (file.empty()) {
      served.json = json::parse(builtin_map_json());
    } else {
      std::ifstream in(file);
      if (!in) return std::unexpected(file + ": cannot open");
      served.json = json::parse(in);
    }
  } catch (const json::exception& e) {
    return std::unexpected((file.empty() ? std::string("built-in map") : file) + ": " + e.what());
  }
  auto map = drivers::parse_register_map(served.json);
  if (!map) return std::unexpected((file.empty() ? std::string("built-in map") : file) + ": " + map.error().message);
  served.map = *map;
  return served;
}

json drivers_config(const Endpoints& where, const ServedMap& map, const std::vector<UnitLayout>& units) {
  auto modbus = [&](int port, int unit) {
    return json{{"transport", "tcp"}, {"host", where.host}, {"port", port}, {"unit_id", unit},
                {"response_timeout_ms", 500}};
  };
  json out;
  out["chamber"] = {{"modbus", modbus(where.chamber_port, where.chamber_unit)}, {"map", map.json}};
  out["thermistors"] = {{"modbus", modbus(where.thermistor_port, where.thermistor_unit)}};
  out["gyro_bus"] = {{"transport", "unix:" + where.can_socket}};
  out["units"] = json::array();
  for (const auto& u : units) {
    json gyro = {{"node_id", u.gyro.node_id}};
    if (u.gyro.axes != 1) gyro["axes"] = u.gyro.axes;
    if (u.gyro.mode == drivers::GyroMode::rate) {
      gyro["mode"] = "rate";
      gyro["scale_dph_per_count"] = u.gyro.scale_dph_per_count;
    } else {
      gyro["mode"] = "increment";
      gyro["scale_deg_per_count"] = u.gyro.scale_deg_per_count;
      gyro["frame_rate_hz"] = u.gyro.frame_rate_hz;
    }
    json thermistors = {{"t1", u.t1_json}, {"t2", u.t2_json}};
    if (!u.axis_json.empty()) {
      thermistors = {{"x", thermistors},
                     {"y", {{"t1", u.axis_json[0][0]}, {"t2", u.axis_json[0][1]}}},
                     {"z", {{"t1", u.axis_json[1][0]}, {"t2", u.axis_json[1][1]}}}};
    }
    out["units"].push_back({{"serial", u.serial}, {"gyro", gyro}, {"thermistors", thermistors}});
  }
  return out;
}

double ntc_resistance_ohm(const drivers::SteinhartHart& sh, double temp_c) noexcept {
  const double inv_t = 1.0 / (temp_c + 273.15);
  if (sh.c == 0.0) return std::exp((inv_t - sh.a) / sh.b);
  // c x^3 + b x + (a - 1/T) = 0 with x = ln R: a depressed cubic with one real root, since
  // b/c > 0 makes its discriminant positive.
  const double y = (sh.a - inv_t) / (2.0 * sh.c);
  const double x = std::sqrt(std::pow(sh.b / (3.0 * sh.c), 3) + y * y);
  return std::exp(std::cbrt(x - y) - std::cbrt(x + y));
}

std::expected<std::array<std::uint16_t, 2>, std::string> encode_thermistor(
    const drivers::ThermistorChannelConfig& channel, double temp_c) {
  const double value = channel.kind == drivers::ThermistorKind::ntc
                           ? ntc_resistance_ohm(channel.coefficients, temp_c)
                           : temp_c;
  auto words = drivers::encode_value(channel.reg, value);
  if (!words) return std::unexpected(words.error().message);
  return *words;
}

std::array<std::uint16_t, 2> encode_open_circuit(const drivers::ThermistorChannelConfig& channel) {
  const auto& reg = channel.reg;
  if (channel.open_circuit_raw) {
    const double raw = *channel.open_circuit_raw;
    if (reg.type == drivers::ValueType::float32) {
      return raw_words(reg, std::bit_cast<std::uint32_t>(static_cast<float>(raw)));
    }
    // Integer types: the raw value's two's-complement bits, whatever the scale.
    return raw_words(reg, static_cast<std::uint32_t>(static_cast<std::int64_t>(std::llround(raw))));
  }
  const double ohm = channel.max_ohm * 10.0;
  if (auto words = drivers::encode_value(reg, ohm)) return *words;
  // The register cannot hold it (a narrow integer): its largest raw value still reads as open
  // or out of range, never as a plausible temperature.
  return raw_words(reg, reg.width() == 2 ? 0x7FFFFFFFu : 0x7FFFu);
}

std::array<std::uint16_t, 2> raw_words(const drivers::RegisterSpec& spec, std::uint32_t raw) noexcept {
  if (spec.width() == 1) return {static_cast<std::uint16_t>(raw & 0xFFFFu), 0};
  const auto high = static_cast<std::uint16_t>(raw >> 16);
  const auto low = static_cast<std::uint16_t>(raw & 0xFFFFu);
  return spec.word_order == drivers::WordOrder::high_first ? std::array{high, low} : std::array{low, high};
}

}  // namespace fogbench::mock
