// Fault names, commands and state; see faults.hpp.
#include "faults.hpp"

#include <charconv>
#include <cmath>
#include <limits>
#include <set>

#include "fogbench/drivers/error.hpp"
#include "fogbench/drivers/known_fields.hpp"

namespace fogbench::mock {

using nlohmann::json;

namespace {

constexpr const char* kFaultAxisNames[] = {"x", "y", "z"};  // silence_axis's axis 0, 1, 2

// The main parameter of each fault: the VALUE of the command-line form.
std::optional<std::string_view> main_parameter(FaultKind kind) {
  switch (kind) {
    case FaultKind::stall_modbus: return "ms";
    case FaultKind::lose_frames:
    case FaultKind::corrupt_frames:
    case FaultKind::serial_garbage:
    case FaultKind::serial_cut:
    case FaultKind::serial_bad_crc: return "fraction";
    case FaultKind::serial_baud: return "baud";
    case FaultKind::lose_burst: return "count";
    case FaultKind::gyro_spike: return "dph";
    case FaultKind::open_thermistor: return "sensor";
    case FaultKind::power_off: return "duration_s";
    case FaultKind::power_cycle: return "off_s";
    case FaultKind::table_fault: return "text";
    case FaultKind::silence_axis: return "axis";
    default: return std::nullopt;
  }
}

std::set<std::string_view> fields_of(FaultKind kind) {
  std::set<std::string_view> f = {"cmd", "name", "on"};
  switch (kind) {
    case FaultKind::refuse_modbus:
    case FaultKind::drop_modbus: f.insert("device"); break;
    case FaultKind::stall_modbus: f.insert({"device", "ms"}); break;
    case FaultKind::freeze_pv:
    case FaultKind::alarm:
    case FaultKind::refuse_setpoint:
    case FaultKind::drop_table: break;
    case FaultKind::table_fault: f.insert("text"); break;
    case FaultKind::lose_frames:
    case FaultKind::corrupt_frames: f.insert({"unit", "fraction"}); break;
    case FaultKind::lose_burst: f.insert({"unit", "count"}); break;
    case FaultKind::open_thermistor: f.insert({"unit", "sensor"}); break;
    case FaultKind::gyro_spike: f.insert({"unit", "dph", "duration_s"}); break;
    case FaultKind::power_off: f.insert({"unit", "duration_s"}); break;
    case FaultKind::power_cycle: f.insert({"unit", "off_s"}); break;
    case FaultKind::silence_axis: f.insert({"unit", "axis"}); break;
    case FaultKind::serial_garbage: f.insert({"fraction", "bytes"}); break;
    case FaultKind::serial_cut:
    case FaultKind::serial_bad_crc: f.insert("fraction"); break;
    case FaultKind::serial_baud: f.insert({"baud", "line_baud"}); break;
  }
  return f;
}

std::expected<double, std::string> number_field(const json& c, const char* key, double min, double max) {
  const auto& v = c.at(key);
  if (!v.is_number()) return std::unexpected(std::string(key) + ": expected a number");
  const double x = v.get<double>();
  if (!std::isfinite(x) || x < min || x > max) {
    return std::unexpected(std::string(key) + ": expected " + drivers::format_number(min) + ".." + drivers::format_number(max) +
                           " (got " + v.dump() + ")");
  }
  return x;
}

}  // namespace

std::string_view to_string(FaultKind kind) noexcept {
  switch (kind) {
    case FaultKind::refuse_modbus: return "refuse_modbus";
    case FaultKind::drop_modbus: return "drop_modbus";
    case FaultKind::stall_modbus: return "stall_modbus";
    case FaultKind::freeze_pv: return "freeze_pv";
    case FaultKind::alarm: return "alarm";
    case FaultKind::lose_frames: return "lose_frames";
    case FaultKind::lose_burst: return "lose_burst";
    case FaultKind::corrupt_frames: return "corrupt_frames";
    case FaultKind::open_thermistor: return "open_thermistor";
    case FaultKind::gyro_spike: return "gyro_spike";
    case FaultKind::power_off: return "power_off";
    case FaultKind::power_cycle: return "power_cycle";
    case FaultKind::refuse_setpoint: return "refuse_setpoint";
    case FaultKind::serial_garbage: return "serial_garbage";
    case FaultKind::serial_cut: return "serial_cut";
    case FaultKind::serial_bad_crc: return "serial_bad_crc";
    case FaultKind::serial_baud: return "serial_baud";
    case FaultKind::table_fault: return "table_fault";
    case FaultKind::drop_table: return "drop_table";
    case FaultKind::silence_axis: return "silence_axis";
  }
  return "?";
}

std::optional<FaultKind> parse_fault_kind(std::string_view name) noexcept {
  for (auto k : all_fault_kinds) {
    if (to_string(k) == name) return k;
  }
  return std::nullopt;
}

std::string_view to_string(Device device) noexcept {
  return device == Device::chamber ? "chamber" : "thermistors";
}

std::expected<FaultCommand, std::string> parse_fault_command(const json& c, const std::vector<std::string>& serials) {
  if (!c.is_object()) return std::unexpected(std::string("a fault command is a JSON object"));
  if (!c.contains("name") || !c["name"].is_string()) return std::unexpected(std::string("name: expected a fault name"));
  const auto name = c["name"].get<std::string>();
  auto kind = parse_fault_kind(name);
  if (!kind) {
    std::string known;
    for (auto k : all_fault_kinds) known += (known.empty() ? "" : ", ") + std::string(to_string(k));
    return std::unexpected("unknown fault '" + name + "' (known: " + known + ")");
  }
  FaultCommand cmd;
  cmd.kind = *kind;
  // The fault's own fields, checked by the one check every file of fogbench shares
  // (drivers/known_fields.hpp) with the fault's name as their path: "power_off.ms: unknown field
  // (known: duration_s, on, unit)". cmd and name, which every command has, are not listed.
  std::vector<std::string_view> own;
  for (auto f : fields_of(*kind)) {
    if (f != "cmd" && f != "name") own.push_back(f);
  }
  json params = c;
  params.erase("cmd");
  params.erase("name");
  if (auto refusal = drivers::unknown_field(params, name, own)) return std::unexpected(std::move(*refusal));
  if (c.contains("on")) {
    if (!c["on"].is_boolean()) return std::unexpected(name + ": on: expected true or false");
    cmd.on = c["on"].get<bool>();
  }
  if (c.contains("device")) {
    const auto& d = c["device"];
    if (d == "chamber") cmd.device = Device::chamber;
    else if (d == "thermistors") cmd.device = Device::thermistors;
    else if (d != "all") return std::unexpected(name + ": device: expected chamber, thermistors or all (got " + d.dump() + ")");
  }
  if (c.contains("unit")) {
    const auto& u = c["unit"];
    if (u.is_number_integer() && u.get<std::int64_t>() >= 0 && static_cast<std::size_t>(u.get<std::int64_t>()) < serials.size()) {
      cmd.unit = static_cast<std::size_t>(u.get<std::int64_t>());
    } else if (u.is_string()) {
      for (std::size_t i = 0; i < serials.size(); ++i) {
        if (serials[i] == u.get<std::string>()) cmd.unit = i;
      }
      if (!cmd.unit && u != "all") return std::unexpected(name + ": unit: no unit has serial " + u.dump());
    } else {
      return std::unexpected(name + ": unit: expected an index 0.." + std::to_string(serials.size() - 1) +
                             " or a serial (got " + u.dump() + ")");
    }
  }
  if (c.contains("sensor")) {
    const auto& s = c["sensor"];
    if (s == "t1" || s == "T1") cmd.sensor = 1;
    else if (s == "t2" || s == "T2") cmd.sensor = 2;
    else if (s != "both") return std::unexpected(name + ": sensor: expected t1, t2 or both (got " + s.dump() + ")");
  }
  if (c.contains("axis")) {
    const auto& a = c["axis"];
    for (std::size_t k = 0; k < 3; ++k)
      if (a == kFaultAxisNames[k] || (a.is_number_integer() && a.get<std::int64_t>() == static_cast<std::int64_t>(k))) cmd.axis = k;
    if (!cmd.axis) return std::unexpected(name + ": axis: expected x, y, z or 0..2 (got " + a.dump() + ")");
  }
  if (cmd.kind == FaultKind::silence_axis && cmd.on && !cmd.axis) return std::unexpected(name + ": axis: missing");
  if (c.contains("text")) {
    if (!c["text"].is_string()) return std::unexpected(name + ": text: expected a string (got " + c["text"].dump() + ")");
    cmd.text = c["text"].get<std::string>();
    if (cmd.text.size() > 80 || cmd.text.find_first_of("\r\n") != std::string::npos) {
      return std::unexpected(name + ": text: expected one line of at most 80 characters");
    }
  }
  // The main parameter is needed to switch a fault on; switching off needs none.
  auto need = [&](const char* key, double min, double max) -> std::expected<double, std::string> {
    if (!c.contains(key)) {
      if (!cmd.on) return 0.0;
      return std::unexpected(name + ": " + key + ": missing");
    }
    auto x = number_field(c, key, min, max);
    if (!x) return std::unexpected(name + ": " + x.error());
    return *x;
  };
  std::expected<double, std::string> v = 0.0;
  switch (cmd.kind) {
    case FaultKind::stall_modbus: v = need("ms", 1, 600000); break;
    case FaultKind::lose_frames:
    case FaultKind::corrupt_frames: v = need("fraction", 0, 1); break;
    case FaultKind::lose_burst: v = need("count", 1, 1000000); break;
    case FaultKind::gyro_spike:
      v = need("dph", -100000, 100000);
      if (v && c.contains("duration_s")) {
        auto d = number_field(c, "duration_s", 1e-9, 1e9);
        if (!d) return std::unexpected(name + ": " + d.error());
        cmd.duration_s = *d;
      }
      break;
    case FaultKind::power_off:
      v = std::numeric_limits<double>::infinity();
      if (cmd.on && c.contains("duration_s")) v = number_field(c, "duration_s", 1e-9, 1e9);
      if (!v) return std::unexpected(name + ": " + v.error());
      break;
    case FaultKind::power_cycle:
      v = default_power_cycle_off_s;
      if (c.contains("off_s")) v = number_field(c, "off_s", 1e-9, 1e9);
      if (!v) return std::unexpected(name + ": " + v.error());
      break;
    case FaultKind::serial_garbage:
      v = need("fraction", 0, 1);
      if (v && c.contains("bytes")) {
        auto b = number_field(c, "bytes", 1, 4096);
        if (!b) return std::unexpected(name + ": " + b.error());
        if (*b != std::floor(*b)) return std::unexpected(name + ": bytes: expected a whole number");
        cmd.bytes = static_cast<int>(*b);
      }
      break;
    case FaultKind::serial_cut:
    case FaultKind::serial_bad_crc: v = need("fraction", 0, 1); break;
    case FaultKind::serial_baud: {
      v = need("baud", 50, 4000000);
      if (v && *v != std::floor(*v)) return std::unexpected(name + ": baud: expected a whole number of bits/s");
      if (v && c.contains("line_baud")) {
        auto b = number_field(c, "line_baud", 50, 4000000);
        if (!b) return std::unexpected(name + ": " + b.error());
        if (*b != std::floor(*b)) return std::unexpected(name + ": line_baud: expected a whole number of bits/s");
        cmd.line_baud = static_cast<int>(*b);
      }
      break;
    }
    default: break;
  }
  if (!v) return std::unexpected(v.error());
  cmd.value = *v;
  return cmd;
}

std::expected<json, std::string> fault_json_from_cli(std::string_view text) {
  json out = {{"cmd", "fault"}, {"on", true}};
  auto to_value = [](std::string_view s) -> json {
    std::int64_t i = 0;
    if (const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), i);
        ec == std::errc() && end == s.data() + s.size() && !s.empty()) {
      return i;  // an integer stays one: "unit=1" is an index
    }
    double x = 0;
    const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), x);
    if (ec == std::errc() && end == s.data() + s.size() && !s.empty()) return x;
    return std::string(s);
  };
  bool first = true;
  std::optional<FaultKind> kind;
  while (true) {
    const auto comma = text.find(',');
    const auto part = text.substr(0, comma);
    const auto eq = part.find('=');
    const auto key = part.substr(0, eq);
    if (key.empty()) return std::unexpected("--fault '" + std::string(text) + "': empty name or key");
    if (first) {
      kind = parse_fault_kind(key);
      if (!kind) return std::unexpected("--fault: unknown fault '" + std::string(key) + "'");
      out["name"] = std::string(key);
      if (eq != std::string_view::npos) {
        const auto param = main_parameter(*kind);
        if (!param) return std::unexpected("--fault " + std::string(key) + " takes no value");
        out[std::string(*param)] = to_value(part.substr(eq + 1));
      }
      first = false;
    } else {
      if (eq == std::string_view::npos) return std::unexpected("--fault: expected KEY=VALUE, got '" + std::string(part) + "'");
      out[std::string(key)] = to_value(part.substr(eq + 1));
    }
    if (comma == std::string_view::npos) break;
    text.remove_prefix(comma + 1);
  }
  return out;
}

void apply_fault(FaultState& state, const FaultCommand& c, double next_second_s) {
  auto each_device = [&](auto f) {
    for (auto d : {Device::chamber, Device::thermistors}) {
      if (!c.device || *c.device == d) f(static_cast<std::size_t>(d));
    }
  };
  auto each_unit = [&](auto f) {
    for (std::size_t i = 0; i < state.units.size(); ++i) {
      if (!c.unit || *c.unit == i) f(state.units[i]);
    }
  };
  switch (c.kind) {
    case FaultKind::refuse_modbus: each_device([&](std::size_t d) { state.refuse[d] = c.on; }); break;
    case FaultKind::drop_modbus: break;
    case FaultKind::stall_modbus:
      each_device([&](std::size_t d) { state.stall_ms[d] = c.on ? static_cast<int>(c.value) : 0; });
      break;
    case FaultKind::freeze_pv: state.freeze_pv = c.on; break;
    case FaultKind::alarm: state.alarm = c.on; break;
    case FaultKind::refuse_setpoint: state.refuse_setpoint = c.on; break;
    case FaultKind::table_fault:
      state.table_fault = c.on;
      state.table_fault_text = c.on ? c.text : std::string();
      break;
    case FaultKind::drop_table:
      if (c.on) ++state.table_drops;
      break;
    case FaultKind::lose_frames: each_unit([&](UnitFaults& u) { u.lose_fraction = c.on ? c.value : 0.0; }); break;
    case FaultKind::lose_burst:
      each_unit([&](UnitFaults& u) { u.lose_burst = c.on ? u.lose_burst + static_cast<std::uint32_t>(c.value) : 0; });
      break;
    case FaultKind::corrupt_frames: each_unit([&](UnitFaults& u) { u.corrupt_fraction = c.on ? c.value : 0.0; }); break;
    case FaultKind::open_thermistor:
      each_unit([&](UnitFaults& u) {
        if (!c.sensor || *c.sensor == 1) u.open_t1 = c.on;
        if (!c.sensor || *c.sensor == 2) u.open_t2 = c.on;
      });
      break;
    case FaultKind::gyro_spike:
      each_unit([&](UnitFaults& u) {
        u.spike_dph = c.on ? c.value : 0.0;
        u.spike_until_s = c.on ? next_second_s + c.duration_s : 0.0;
      });
      break;
    case FaultKind::power_off:
      each_unit([&](UnitFaults& u) {
        if (c.on) {
          u.power_off_from_s = next_second_s;
          u.power_on_at_s = next_second_s + c.value;
        } else if (u.power_on_at_s > next_second_s) {
          // Back on from the next second; a power-off not yet begun is simply cancelled.
          if (u.power_off_from_s >= next_second_s) u.power_off_from_s = std::numeric_limits<double>::infinity();
          u.power_on_at_s = next_second_s;
        }
      });
      break;
    case FaultKind::power_cycle:
      if (!c.on) break;  // an action: nothing to switch off
      each_unit([&](UnitFaults& u) {
        u.power_off_from_s = next_second_s;
        u.power_on_at_s = next_second_s + c.value;
      });
      break;
    case FaultKind::silence_axis:
      each_unit([&](UnitFaults& u) {
        for (std::size_t k = 0; k < u.silent_axis.size(); ++k)
          if (!c.axis || *c.axis == k) u.silent_axis[k] = c.on;
      });
      break;
    case FaultKind::serial_garbage:
      state.serial.garbage_fraction = c.on ? c.value : 0.0;
      state.serial.garbage_bytes = c.bytes;
      break;
    case FaultKind::serial_cut: state.serial.cut_fraction = c.on ? c.value : 0.0; break;
    case FaultKind::serial_bad_crc: state.serial.bad_crc_fraction = c.on ? c.value : 0.0; break;
    case FaultKind::serial_baud:
      state.serial.baud = c.on ? static_cast<int>(c.value) : 0;
      state.serial.line_baud = c.line_baud;
      break;
  }
}

json active_faults(const FaultState& s, const std::vector<std::string>& serials, double next_second_s) {
  json out = json::array();
  for (auto d : {Device::chamber, Device::thermistors}) {
    const auto i = static_cast<std::size_t>(d);
    if (s.refuse[i]) out.push_back({{"name", "refuse_modbus"}, {"device", to_string(d)}});
    if (s.stall_ms[i] > 0) out.push_back({{"name", "stall_modbus"}, {"device", to_string(d)}, {"ms", s.stall_ms[i]}});
  }
  if (s.freeze_pv) out.push_back({{"name", "freeze_pv"}});
  if (s.alarm) out.push_back({{"name", "alarm"}});
  if (s.refuse_setpoint) out.push_back({{"name", "refuse_setpoint"}});
  if (s.serial.garbage_fraction > 0) {
    out.push_back({{"name", "serial_garbage"}, {"fraction", s.serial.garbage_fraction}, {"bytes", s.serial.garbage_bytes}});
  }
  if (s.serial.cut_fraction > 0) out.push_back({{"name", "serial_cut"}, {"fraction", s.serial.cut_fraction}});
  if (s.serial.bad_crc_fraction > 0) out.push_back({{"name", "serial_bad_crc"}, {"fraction", s.serial.bad_crc_fraction}});
  if (s.serial.baud > 0) {
    out.push_back({{"name", "serial_baud"}, {"baud", s.serial.baud}, {"line_baud", s.serial.line_baud}});
  }
  if (s.table_fault) out.push_back({{"name", "table_fault"}, {"text", s.table_fault_text}});
  for (std::size_t i = 0; i < s.units.size(); ++i) {
    const auto& u = s.units[i];
    const json unit = {{"unit", i}, {"serial", i < serials.size() ? serials[i] : ""}};
    auto with = [&](json j) {
      j.update(unit);
      out.push_back(std::move(j));
    };
    if (u.lose_fraction > 0) with({{"name", "lose_frames"}, {"fraction", u.lose_fraction}});
    if (u.lose_burst > 0) with({{"name", "lose_burst"}, {"count", u.lose_burst}});
    if (u.corrupt_fraction > 0) with({{"name", "corrupt_frames"}, {"fraction", u.corrupt_fraction}});
    for (std::size_t k = 0; k < u.silent_axis.size(); ++k)
      if (u.silent_axis[k]) with({{"name", "silence_axis"}, {"axis", kFaultAxisNames[k]}});
    if (u.open_t1) with({{"name", "open_thermistor"}, {"sensor", "t1"}});
    if (u.open_t2) with({{"name", "open_thermistor"}, {"sensor", "t2"}});
    if (u.spike_until_s > next_second_s) with({{"name", "gyro_spike"}, {"dph", u.spike_dph}, {"until_s", u.spike_until_s}});
    if (std::isfinite(u.power_off_from_s) && u.power_on_at_s > next_second_s) {
      with({{"name", "power_off"}, {"from_s", u.power_off_from_s},
            {"until_s", std::isfinite(u.power_on_at_s) ? json(u.power_on_at_s) : json(nullptr)}});
    }
  }
  return out;
}

}  // namespace fogbench::mock
