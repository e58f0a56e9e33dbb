// Register descriptions, chamber map validation and word <-> value conversions.
#include "fogbench/drivers/register_map.hpp"

#include <nlohmann/json.hpp>

#include <bit>
#include <cmath>
#include <fstream>
#include <limits>
#include <sstream>
#include <vector>

#include "json_fields.hpp"

namespace fogbench::drivers {

using detail::config_error;
using detail::join_path;
using nlohmann::json;

std::string_view to_string(RegisterFunction function) noexcept {
  switch (function) {
    case RegisterFunction::holding: return "holding";
    case RegisterFunction::input: return "input";
    case RegisterFunction::coil: return "coil";
    case RegisterFunction::discrete: return "discrete";
  }
  return "?";
}

std::string_view to_string(ValueType type) noexcept {
  switch (type) {
    case ValueType::boolean: return "bool";
    case ValueType::int16: return "int16";
    case ValueType::uint16: return "uint16";
    case ValueType::int32: return "int32";
    case ValueType::uint32: return "uint32";
    case ValueType::float32: return "float32";
  }
  return "?";
}

std::string_view to_string(WordOrder order) noexcept {
  return order == WordOrder::high_first ? "high_first" : "low_first";
}

bool is_bit_table(RegisterFunction function) noexcept {
  return function == RegisterFunction::coil || function == RegisterFunction::discrete;
}

bool is_writable(RegisterFunction function) noexcept {
  return function == RegisterFunction::holding || function == RegisterFunction::coil;
}

std::uint16_t RegisterSpec::width() const noexcept {
  return (type == ValueType::int32 || type == ValueType::uint32 || type == ValueType::float32) ? 2
                                                                                                : 1;
}

std::string RegisterSpec::describe() const {
  std::string out{to_string(function)};
  out += ' ';
  out += std::to_string(address);
  if (width() == 2) out += ".." + std::to_string(address + 1);
  if (!is_bit_table(function)) {
    out += " (";
    out += to_string(type);
    if (width() == 2) {
      out += ", ";
      out += to_string(word_order);
    }
    out += ')';
  }
  return out;
}

std::uint32_t raw_unsigned(const RegisterSpec& spec, std::span<const std::uint16_t> words) noexcept {
  if (spec.width() == 1) return words[0];
  const std::uint32_t first = words[0];
  const std::uint32_t second = words[1];
  return spec.word_order == WordOrder::high_first ? (first << 16) | second : (second << 16) | first;
}

Result<double> decode_value(const RegisterSpec& spec, std::span<const std::uint16_t> words) {
  auto raw = decode_raw(spec, words);
  if (!raw) return raw;
  return *raw * spec.scale + spec.offset;
}

Result<double> decode_raw(const RegisterSpec& spec, std::span<const std::uint16_t> words) {
  const std::uint32_t u = raw_unsigned(spec, words);
  double raw = 0;
  switch (spec.type) {
    case ValueType::boolean: raw = u != 0 ? 1.0 : 0.0; break;
    case ValueType::int16: raw = static_cast<std::int16_t>(static_cast<std::uint16_t>(u)); break;
    case ValueType::uint16: raw = static_cast<std::uint16_t>(u); break;
    case ValueType::int32: raw = static_cast<std::int32_t>(u); break;
    case ValueType::uint32: raw = u; break;
    case ValueType::float32: {
      const float f = std::bit_cast<float>(u);
      if (!std::isfinite(f)) {
        return fail(ErrorCode::corrupt, spec.describe() + ": not a finite number");
      }
      raw = f;
      break;
    }
  }
  return raw;
}

Result<std::array<std::uint16_t, 2>> encode_value(const RegisterSpec& spec, double value) {
  auto out_of_range = [&](double lo, double hi) {
    return fail(ErrorCode::out_of_range,
                format_number(value) + " is not representable in " + spec.describe() +
                    " with scale " + format_number(spec.scale) + " and offset " +
                    format_number(spec.offset) + " (raw range " + format_number(lo) + ".." +
                    format_number(hi) + ")");
  };
  if (!std::isfinite(value)) return out_of_range(0, 0);
  const double raw = (value - spec.offset) / spec.scale;
  std::uint32_t u = 0;
  auto integral = [&](double lo, double hi) -> bool {
    const double r = std::nearbyint(raw);
    if (r < lo || r > hi) return false;
    u = static_cast<std::uint32_t>(static_cast<std::int64_t>(r));
    return true;
  };
  switch (spec.type) {
    case ValueType::boolean: u = raw != 0 ? 1 : 0; break;
    case ValueType::int16:
      if (!integral(-32768, 32767)) return out_of_range(-32768, 32767);
      u &= 0xFFFFu;
      break;
    case ValueType::uint16:
      if (!integral(0, 65535)) return out_of_range(0, 65535);
      break;
    case ValueType::int32:
      if (!integral(-2147483648.0, 2147483647.0)) return out_of_range(-2147483648.0, 2147483647.0);
      break;
    case ValueType::uint32:
      if (!integral(0, 4294967295.0)) return out_of_range(0, 4294967295.0);
      break;
    case ValueType::float32: {
      constexpr double max = std::numeric_limits<float>::max();
      if (std::fabs(raw) > max) return out_of_range(-max, max);
      u = std::bit_cast<std::uint32_t>(static_cast<float>(raw));
      break;
    }
  }
  std::array<std::uint16_t, 2> words{};
  if (spec.width() == 1) {
    words[0] = static_cast<std::uint16_t>(u);
  } else {
    const auto high = static_cast<std::uint16_t>(u >> 16);
    const auto low = static_cast<std::uint16_t>(u);
    words = spec.word_order == WordOrder::high_first ? std::array{high, low} : std::array{low, high};
  }
  return words;
}

// ---- parsing -------------------------------------------------------------------------------

namespace {

constexpr std::string_view register_types = "int16, uint16, int32, uint32, float32";

std::optional<RegisterFunction> function_from(std::string_view s) {
  if (s == "holding") return RegisterFunction::holding;
  if (s == "input") return RegisterFunction::input;
  if (s == "coil") return RegisterFunction::coil;
  if (s == "discrete") return RegisterFunction::discrete;
  return std::nullopt;
}

std::optional<ValueType> type_from(std::string_view s) {
  if (s == "int16") return ValueType::int16;
  if (s == "uint16") return ValueType::uint16;
  if (s == "int32") return ValueType::int32;
  if (s == "uint32") return ValueType::uint32;
  if (s == "float32") return ValueType::float32;
  return std::nullopt;
}

}  // namespace

Result<RegisterSpec> parse_register_spec(const json& value, const std::string& path,
                                         std::span<const std::string_view> extra_keys) {
  if (auto ok = detail::expect_object(value, path); !ok) return std::unexpected(ok.error());
  static constexpr std::string_view common[] = {"function", "address", "type", "word_order",
                                                "scale",    "offset",  "description"};
  std::vector<std::string_view> known(std::begin(common), std::end(common));
  known.insert(known.end(), extra_keys.begin(), extra_keys.end());
  if (auto ok = detail::expect_known_keys(value, path, known); !ok) return std::unexpected(ok.error());

  RegisterSpec spec;
  auto function = detail::get_string(value, path, "function");
  if (!function) return std::unexpected(function.error());
  auto f = function_from(*function);
  if (!f) {
    return config_error(join_path(path, "function"),
                        "unknown function '" + *function + "' (expected holding, input, coil, discrete)");
  }
  spec.function = *f;

  if (is_bit_table(spec.function)) {
    spec.type = ValueType::boolean;
    if (value.contains("type")) {
      auto type = detail::get_string(value, path, "type");
      if (!type) return std::unexpected(type.error());
      if (*type != "bool") {
        return config_error(join_path(path, "type"),
                            "'" + *type + "' on a " + *function + ": bits are 'bool' (or omit type)");
      }
    }
  } else {
    auto type = detail::get_string(value, path, "type");
    if (!type) {
      return config_error(join_path(path, "type"),
                          "missing (expected " + std::string(register_types) + ")");
    }
    auto t = type_from(*type);
    if (!t) {
      return config_error(join_path(path, "type"), "unknown type '" + *type + "' (expected " +
                                                       std::string(register_types) + ")");
    }
    spec.type = *t;
  }

  // The last register of a 32-bit value must exist too.
  auto address = detail::get_int(value, path, "address", 0, 65536 - spec.width());
  if (!address) return std::unexpected(address.error());
  spec.address = static_cast<std::uint16_t>(*address);

  auto order = detail::get_string_or(value, path, "word_order", "high_first");
  if (!order) return std::unexpected(order.error());
  if (*order == "high_first") {
    spec.word_order = WordOrder::high_first;
  } else if (*order == "low_first") {
    spec.word_order = WordOrder::low_first;
  } else {
    return config_error(join_path(path, "word_order"),
                        "unknown word order '" + *order + "' (expected high_first, low_first)");
  }

  auto scale = detail::get_number_or(value, path, "scale", 1.0);
  if (!scale) return std::unexpected(scale.error());
  if (*scale == 0.0) return config_error(join_path(path, "scale"), "must not be 0");
  spec.scale = *scale;
  auto offset = detail::get_number_or(value, path, "offset", 0.0);
  if (!offset) return std::unexpected(offset.error());
  spec.offset = *offset;
  return spec;
}

namespace {

struct Named {
  std::string_view name;
  const RegisterSpec* spec;
};

}  // namespace

Result<RegisterMap> parse_register_map(const json& value, const std::string& path) {
  if (auto ok = detail::expect_object(value, path); !ok) return std::unexpected(ok.error());
  if (auto ok = detail::expect_known_keys(value, path, {"name", "source", "notes", "registers"}); !ok) {
    return std::unexpected(ok.error());
  }
  RegisterMap map;
  auto name = detail::get_string_or(value, path, "name", "");
  if (!name) return std::unexpected(name.error());
  map.name = *name;
  auto source = detail::get_string_or(value, path, "source", "");
  if (!source) return std::unexpected(source.error());
  map.source = *source;

  const auto regs_path = join_path(path, "registers");
  auto regs_it = value.find("registers");
  if (regs_it == value.end()) return config_error(regs_path, "missing (expected an object)");
  const json& regs = *regs_it;
  if (auto ok = detail::expect_object(regs, regs_path); !ok) return std::unexpected(ok.error());

  static constexpr std::string_view known[] = {"setpoint", "process_value", "run",     "alarm",
                                               "status",   "identity",      "units"};
  static constexpr std::string_view required[] = {"setpoint", "process_value", "run", "alarm"};
  for (auto it = regs.begin(); it != regs.end(); ++it) {
    bool ok = false;
    for (auto k : known) ok = ok || it.key() == k;
    if (!ok) {
      return config_error(join_path(regs_path, it.key()),
                          "unknown register (known: setpoint, process_value, run, alarm, status, "
                          "identity, units)");
    }
  }
  for (auto k : required) {
    if (!regs.contains(k)) {
      return config_error(join_path(regs_path, k),
                          "missing (required: setpoint, process_value, run, alarm)");
    }
  }

  auto reg_path = [&](std::string_view reg) { return join_path(regs_path, reg); };

  {  // setpoint: written, so a holding register
    const auto p = reg_path("setpoint");
    auto spec = parse_register_spec(regs["setpoint"], p);
    if (!spec) return std::unexpected(spec.error());
    if (spec->function != RegisterFunction::holding) {
      return config_error(join_path(p, "function"),
                          "'" + std::string(to_string(spec->function)) +
                              "' cannot be written; setpoint is written (expected holding)");
    }
    map.setpoint = *spec;
  }
  {  // process value: read from any register table
    const auto p = reg_path("process_value");
    auto spec = parse_register_spec(regs["process_value"], p);
    if (!spec) return std::unexpected(spec.error());
    if (is_bit_table(spec->function)) {
      return config_error(join_path(p, "function"),
                          "'" + std::string(to_string(spec->function)) +
                              "' holds bits; process_value is a number (expected holding or input)");
    }
    map.process_value = *spec;
  }
  {  // run/stop: written, a coil or a holding register with on/off values
    const auto p = reg_path("run");
    static constexpr std::string_view extra[] = {"on", "off"};
    const json& j = regs["run"];
    auto spec = parse_register_spec(j, p, extra);
    if (!spec) return std::unexpected(spec.error());
    if (!is_writable(spec->function)) {
      return config_error(join_path(p, "function"),
                          "'" + std::string(to_string(spec->function)) +
                              "' cannot be written; run is written (expected coil or holding)");
    }
    map.run.reg = *spec;
    if (spec->function == RegisterFunction::coil && (j.contains("on") || j.contains("off"))) {
      return config_error(join_path(p, j.contains("on") ? "on" : "off"),
                          "only for a holding register (a coil is written 1/0)");
    }
    if (spec->width() != 1 && spec->function == RegisterFunction::holding) {
      return config_error(join_path(p, "type"), "run is one register (expected int16 or uint16)");
    }
    auto on = detail::get_int_or(j, p, "on", 0, 65535, 1);
    if (!on) return std::unexpected(on.error());
    auto off = detail::get_int_or(j, p, "off", 0, 65535, 0);
    if (!off) return std::unexpected(off.error());
    if (*on == *off) return config_error(join_path(p, "off"), "must differ from on");
    map.run.on_value = static_cast<std::uint16_t>(*on);
    map.run.off_value = static_cast<std::uint16_t>(*off);
  }
  {  // alarm: a bit, or a register whose masked bits mean alarm
    const auto p = reg_path("alarm");
    static constexpr std::string_view extra[] = {"mask"};
    const json& j = regs["alarm"];
    auto spec = parse_register_spec(j, p, extra);
    if (!spec) return std::unexpected(spec.error());
    map.alarm.reg = *spec;
    if (j.contains("mask")) {
      if (is_bit_table(spec->function)) {
        return config_error(join_path(p, "mask"), "only for a register (a bit is its own alarm)");
      }
      const std::int64_t max = spec->width() == 2 ? 0xFFFFFFFFll : 0xFFFFll;
      auto mask = detail::get_int(j, p, "mask", 1, max);
      if (!mask) return std::unexpected(mask.error());
      map.alarm.mask = static_cast<std::uint32_t>(*mask);
    }
  }
  if (regs.contains("status")) {
    const auto p = reg_path("status");
    static constexpr std::string_view extra[] = {"bits"};
    const json& j = regs["status"];
    auto spec = parse_register_spec(j, p, extra);
    if (!spec) return std::unexpected(spec.error());
    StatusSpec status{*spec, {}};
    if (auto it = j.find("bits"); it != j.end()) {
      const auto bp = join_path(p, "bits");
      if (auto ok = detail::expect_object(*it, bp); !ok) return std::unexpected(ok.error());
      const int max_bit = is_bit_table(spec->function) ? 0 : spec->width() * 16 - 1;
      for (auto b = it->begin(); b != it->end(); ++b) {
        auto bit = detail::get_int(*it, bp, b.key(), 0, max_bit);
        if (!bit) return std::unexpected(bit.error());
        status.bits.emplace_back(b.key(), static_cast<int>(*bit));
      }
    }
    map.status = std::move(status);
  }
  for (std::string_view checked : {"identity", "units"}) {
    if (!regs.contains(checked)) continue;
    const auto p = reg_path(checked);
    static constexpr std::string_view extra[] = {"expect"};
    const json& j = regs[std::string(checked)];
    auto spec = parse_register_spec(j, p, extra);
    if (!spec) return std::unexpected(spec.error());
    CheckedSpec c{*spec, std::nullopt};
    if (j.contains("expect")) {
      const std::int64_t max = is_bit_table(spec->function) ? 1
                               : spec->width() == 2         ? 0xFFFFFFFFll
                                                            : 0xFFFFll;
      auto expect = detail::get_int(j, p, "expect", 0, max);
      if (!expect) return std::unexpected(expect.error());
      c.expect = static_cast<std::uint32_t>(*expect);
    }
    (checked == "identity" ? map.identity : map.units) = c;
  }

  // Two names for one register would make a write to one silently change the other.
  std::vector<Named> present = {{"setpoint", &map.setpoint},
                                {"process_value", &map.process_value},
                                {"run", &map.run.reg},
                                {"alarm", &map.alarm.reg}};
  if (map.status) present.push_back({"status", &map.status->reg});
  if (map.identity) present.push_back({"identity", &map.identity->reg});
  if (map.units) present.push_back({"units", &map.units->reg});
  for (std::size_t i = 1; i < present.size(); ++i) {
    for (std::size_t j = 0; j < i; ++j) {
      const RegisterSpec& a = *present[i].spec;
      const RegisterSpec& b = *present[j].spec;
      if (a.function != b.function) continue;
      const int a_end = a.address + a.width();
      const int b_end = b.address + b.width();
      if (a.address < b_end && b.address < a_end) {
        return config_error(join_path(reg_path(present[i].name), "address"),
                            a.describe() + " overlaps registers." + std::string(present[j].name) +
                                " (" + b.describe() + ")");
      }
    }
  }
  return map;
}

Result<RegisterMap> load_register_map(const std::string& file_path) {
  std::ifstream in(file_path);
  if (!in) return fail(ErrorCode::config, file_path + ": cannot open");
  std::ostringstream text;
  text << in.rdbuf();
  // nlohmann throws on syntax errors; the exception stays inside this function.
  json doc;
  try {
    doc = json::parse(text.str());
  } catch (const json::parse_error& e) {
    return fail(ErrorCode::config, file_path + ": not valid JSON: " + e.what());
  }
  auto map = parse_register_map(doc);
  if (!map) {
    return fail(ErrorCode::config, file_path + ": " + map.error().message);
  }
  return map;
}

}  // namespace fogbench::drivers
