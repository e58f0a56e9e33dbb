// Thermistor reading -> temperature, with open-circuit and range checks, and its configuration.
#include "fogbench/drivers/thermistor_conversion.hpp"

#include <nlohmann/json.hpp>

#include <cmath>

#include "json_fields.hpp"

namespace fogbench::drivers {

using detail::config_error;
using detail::join_path;

double SteinhartHart::temp_c(double resistance_ohm) const noexcept {
  const double ln_r = std::log(resistance_ohm);
  const double inv_t_k = a + b * ln_r + c * ln_r * ln_r * ln_r;
  return 1.0 / inv_t_k - 273.15;
}

Result<double> convert_thermistor(const ThermistorChannelConfig& channel,
                                  std::span<const std::uint16_t> words, std::string_view who) {
  const std::string name(who);
  auto raw = decode_raw(channel.reg, words);
  if (!raw) return fail(raw.error().code, name + ": " + raw.error().message);
  if (channel.open_circuit_raw && *raw == *channel.open_circuit_raw) {
    return fail(ErrorCode::open_circuit,
                name + ": open circuit (module reports " + format_number(*raw) + ")");
  }
  const double value = *raw * channel.reg.scale + channel.reg.offset;
  double temp_c = value;
  if (channel.kind == ThermistorKind::ntc) {
    if (value >= channel.max_ohm) {
      return fail(ErrorCode::open_circuit, name + ": open circuit (resistance " +
                                               format_number(value) + " ohm, limit " +
                                               format_number(channel.max_ohm) + " ohm)");
    }
    if (value <= channel.min_ohm) {
      return fail(ErrorCode::out_of_range, name + ": short circuit (resistance " +
                                               format_number(value) + " ohm, limit " +
                                               format_number(channel.min_ohm) + " ohm)");
    }
    temp_c = channel.coefficients.temp_c(value);
  }
  if (!std::isfinite(temp_c) || temp_c < channel.min_c || temp_c > channel.max_c) {
    return fail(ErrorCode::out_of_range, name + ": " + format_number(temp_c) +
                                             " degC outside " + format_number(channel.min_c) +
                                             ".." + format_number(channel.max_c) + " degC");
  }
  return temp_c;
}

Result<ThermistorChannelConfig> parse_thermistor_channel(const nlohmann::json& value,
                                                         const std::string& path) {
  static constexpr std::string_view extra[] = {"kind", "steinhart_hart", "valid_c", "valid_ohm",
                                               "open_circuit_raw"};
  auto reg = parse_register_spec(value, path, extra);
  if (!reg) return std::unexpected(reg.error());
  ThermistorChannelConfig ch;
  ch.reg = *reg;
  if (is_bit_table(ch.reg.function)) {
    return config_error(join_path(path, "function"),
                        "'" + std::string(to_string(ch.reg.function)) +
                            "' holds bits; a thermistor is a number (expected holding or input)");
  }
  auto kind = detail::get_string(value, path, "kind");
  if (!kind) return std::unexpected(kind.error());
  if (*kind == "temperature") {
    ch.kind = ThermistorKind::temperature;
    if (value.contains("steinhart_hart") || value.contains("valid_ohm")) {
      return config_error(join_path(path, value.contains("steinhart_hart") ? "steinhart_hart"
                                                                           : "valid_ohm"),
                          "only for kind 'ntc'");
    }
  } else if (*kind == "ntc") {
    ch.kind = ThermistorKind::ntc;
    const auto sh_path = join_path(path, "steinhart_hart");
    auto sh = value.find("steinhart_hart");
    if (sh == value.end()) return config_error(sh_path, "missing (expected {\"a\", \"b\", \"c\"})");
    if (auto ok = detail::expect_object(*sh, sh_path); !ok) return std::unexpected(ok.error());
    if (auto ok = detail::expect_known_keys(*sh, sh_path, {"a", "b", "c"}); !ok) {
      return std::unexpected(ok.error());
    }
    auto a = detail::get_number(*sh, sh_path, "a");
    if (!a) return std::unexpected(a.error());
    auto b = detail::get_number(*sh, sh_path, "b");
    if (!b) return std::unexpected(b.error());
    auto c = detail::get_number(*sh, sh_path, "c");
    if (!c) return std::unexpected(c.error());
    ch.coefficients = {*a, *b, *c};
    // b carries the curve: without it the temperature would not depend on the resistance.
    if (*b <= 0) return config_error(join_path(sh_path, "b"), "must be positive for an NTC");
    auto ohm = detail::get_range_or(value, path, "valid_ohm", {ch.min_ohm, ch.max_ohm});
    if (!ohm) return std::unexpected(ohm.error());
    if (ohm->min <= 0) return config_error(join_path(join_path(path, "valid_ohm"), "min"), "must be positive");
    ch.min_ohm = ohm->min;
    ch.max_ohm = ohm->max;
  } else {
    return config_error(join_path(path, "kind"),
                        "unknown kind '" + *kind + "' (expected temperature, ntc)");
  }
  auto valid = detail::get_range_or(value, path, "valid_c", {ch.min_c, ch.max_c});
  if (!valid) return std::unexpected(valid.error());
  ch.min_c = valid->min;
  ch.max_c = valid->max;
  if (value.contains("open_circuit_raw")) {
    auto raw = detail::get_number(value, path, "open_circuit_raw");
    if (!raw) return std::unexpected(raw.error());
    ch.open_circuit_raw = *raw;
  }
  return ch;
}

}  // namespace fogbench::drivers
