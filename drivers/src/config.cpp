// Parsing of the drivers' configuration from JSON, with field-path errors.
#include "fogbench/drivers/config.hpp"

#include <nlohmann/json.hpp>

#include <fstream>
#include <map>

#include "fogbench/drivers/can_transport.hpp"
#include "fogbench/drivers/chamber_registry.hpp"
#include "json_fields.hpp"

namespace fogbench::drivers {

using detail::config_error;
using detail::index_path;
using detail::join_path;
using nlohmann::json;

#define FOGBENCH_TRY(var, expr)                      \
  auto var = (expr);                                 \
  if (!var) return std::unexpected(var.error())

std::string ModbusEndpoint::describe() const {
  std::string out;
  if (transport == Transport::tcp) {
    out = "tcp " + host + ":" + std::to_string(port);
  } else {
    out = "rtu " + device + " " + std::to_string(baud) + " " + std::to_string(data_bits) +
          parity + std::to_string(stop_bits);
  }
  return out + " unit " + std::to_string(unit_id);
}

namespace {

// {"initial_ms", "max_ms", "multiplier"}, each optional over `fallback`: one shape for every link.
Result<BackoffConfig> parse_backoff(const json& value, const std::string& bp, BackoffConfig fallback) {
  if (auto ok = detail::expect_object(value, bp); !ok) return std::unexpected(ok.error());
  if (auto ok = detail::expect_known_keys(value, bp, {"initial_ms", "max_ms", "multiplier"}); !ok) {
    return std::unexpected(ok.error());
  }
  FOGBENCH_TRY(initial, detail::get_int_or(value, bp, "initial_ms", 1, 3600000, fallback.initial_ms));
  FOGBENCH_TRY(max, detail::get_int_or(value, bp, "max_ms", 1, 3600000, fallback.max_ms));
  FOGBENCH_TRY(mult, detail::get_number_or(value, bp, "multiplier", fallback.multiplier));
  if (*max < *initial) {
    return config_error(join_path(bp, "max_ms"), "must be at least initial_ms (" + std::to_string(*initial) + ")");
  }
  if (*mult < 1.0 || *mult > 10.0) return config_error(join_path(bp, "multiplier"), "expected a number 1..10");
  return BackoffConfig{*initial, *max, *mult};
}

}  // namespace

Result<ModbusEndpoint> parse_modbus_endpoint(const json& value, const std::string& path) {
  if (auto ok = detail::expect_object(value, path); !ok) return std::unexpected(ok.error());
  if (auto ok = detail::expect_known_keys(
          value, path,
          {"transport", "host", "port", "device", "baud", "parity", "data_bits", "stop_bits",
           "unit_id", "response_timeout_ms", "backoff"});
      !ok) {
    return std::unexpected(ok.error());
  }
  ModbusEndpoint ep;
  FOGBENCH_TRY(transport, detail::get_string(value, path, "transport"));
  if (*transport == "tcp") {
    ep.transport = ModbusEndpoint::Transport::tcp;
    FOGBENCH_TRY(host, detail::get_string(value, path, "host"));
    if (host->empty()) return config_error(join_path(path, "host"), "must not be empty");
    ep.host = *host;
    FOGBENCH_TRY(port, detail::get_int_or(value, path, "port", 1, 65535, 502));
    ep.port = static_cast<std::uint16_t>(*port);
    for (auto k : {"device", "baud", "parity", "data_bits", "stop_bits"}) {
      if (value.contains(k)) return config_error(join_path(path, k), "only for transport 'rtu'");
    }
  } else if (*transport == "rtu") {
    ep.transport = ModbusEndpoint::Transport::rtu;
    FOGBENCH_TRY(device, detail::get_string(value, path, "device"));
    if (device->empty()) return config_error(join_path(path, "device"), "must not be empty");
    ep.device = *device;
    FOGBENCH_TRY(baud, detail::get_int_or(value, path, "baud", 300, 4000000, 19200));
    ep.baud = static_cast<int>(*baud);
    FOGBENCH_TRY(parity, detail::get_string_or(value, path, "parity", "none"));
    if (*parity == "none") {
      ep.parity = 'N';
    } else if (*parity == "even") {
      ep.parity = 'E';
    } else if (*parity == "odd") {
      ep.parity = 'O';
    } else {
      return config_error(join_path(path, "parity"),
                          "unknown parity '" + *parity + "' (expected none, even, odd)");
    }
    FOGBENCH_TRY(data_bits, detail::get_int_or(value, path, "data_bits", 7, 8, 8));
    ep.data_bits = static_cast<int>(*data_bits);
    FOGBENCH_TRY(stop_bits, detail::get_int_or(value, path, "stop_bits", 1, 2, 1));
    ep.stop_bits = static_cast<int>(*stop_bits);
    for (auto k : {"host", "port"}) {
      if (value.contains(k)) return config_error(join_path(path, k), "only for transport 'tcp'");
    }
  } else {
    return config_error(join_path(path, "transport"),
                        "unknown transport '" + *transport + "' (expected tcp, rtu)");
  }
  // 0 is broadcast and 248..255 are reserved by the Modbus specification.
  FOGBENCH_TRY(unit_id, detail::get_int_or(value, path, "unit_id", 1, 247, 1));
  ep.unit_id = static_cast<int>(*unit_id);
  FOGBENCH_TRY(timeout, detail::get_int_or(value, path, "response_timeout_ms", 1, 60000, 1000));
  ep.response_timeout_ms = static_cast<int>(*timeout);

  if (auto it = value.find("backoff"); it != value.end()) {
    FOGBENCH_TRY(backoff, parse_backoff(*it, join_path(path, "backoff"), ep.backoff));
    ep.backoff = *backoff;
  }
  return ep;
}

namespace {

Result<LimitsC> parse_limits(const json& value, const std::string& path, std::string_view key,
                             LimitsC fallback) {
  FOGBENCH_TRY(range, detail::get_range_or(value, path, key, {fallback.min_c, fallback.max_c}));
  return LimitsC{range->min, range->max};
}

}  // namespace

Result<void> parse_modbus_chamber_fields(const json& value, const std::string& path,
                                         const std::filesystem::path& map_dir, ChamberConfig& cfg) {
  const auto mp = join_path(path, "modbus");
  if (!value.contains("modbus")) return config_error(mp, "missing (expected an object)");
  FOGBENCH_TRY(modbus, parse_modbus_endpoint(value["modbus"], mp));
  cfg.modbus = *modbus;

  const auto map_path = join_path(path, "map");
  auto map_it = value.find("map");
  if (map_it == value.end()) {
    return config_error(map_path, "missing (expected a map file name or an inline map object)");
  }
  if (map_it->is_string()) {
    std::filesystem::path file = map_it->get<std::string>();
    if (file.is_relative()) file = map_dir / file;
    auto map = load_register_map(file.string());
    if (!map) return config_error(map_path, map.error().message);
    cfg.map = *map;
    cfg.map_file = file.string();
  } else {
    FOGBENCH_TRY(map, parse_register_map(*map_it, map_path));
    cfg.map = *map;
  }
  return {};
}

Result<LineEndpoint> parse_line_endpoint(const json& value, const std::string& path,
                                         std::uint16_t default_port, bool serial_allowed) {
  if (auto ok = detail::expect_object(value, path); !ok) return std::unexpected(ok.error());
  if (auto ok = detail::expect_known_keys(
          value, path,
          {"transport", "host", "port", "device", "baud", "parity", "data_bits", "stop_bits",
           "response_timeout_ms", "backoff"});
      !ok) {
    return std::unexpected(ok.error());
  }
  LineEndpoint ep;
  FOGBENCH_TRY(transport, detail::get_string(value, path, "transport"));
  if (*transport == "tcp") {
    ep.transport = LineEndpoint::Transport::tcp;
    FOGBENCH_TRY(host, detail::get_string(value, path, "host"));
    if (host->empty()) return config_error(join_path(path, "host"), "must not be empty");
    ep.host = *host;
    FOGBENCH_TRY(port, detail::get_int_or(value, path, "port", 1, 65535, default_port));
    ep.port = static_cast<std::uint16_t>(*port);
    for (auto k : {"device", "baud", "parity", "data_bits", "stop_bits"}) {
      if (value.contains(k)) return config_error(join_path(path, k), "only for transport 'serial'");
    }
  } else if (*transport == "serial" && serial_allowed) {
    ep.transport = LineEndpoint::Transport::serial;
    FOGBENCH_TRY(device, detail::get_string(value, path, "device"));
    if (device->empty()) return config_error(join_path(path, "device"), "must not be empty");
    ep.device = *device;
    FOGBENCH_TRY(baud, detail::get_int_or(value, path, "baud", 1200, 115200, 9600));
    if (*baud != 1200 && *baud != 2400 && *baud != 4800 && *baud != 9600 && *baud != 19200 &&
        *baud != 38400 && *baud != 57600 && *baud != 115200) {
      return config_error(join_path(path, "baud"),
                          "expected 1200, 2400, 4800, 9600, 19200, 38400, 57600 or 115200");
    }
    ep.baud = static_cast<int>(*baud);
    FOGBENCH_TRY(parity, detail::get_string_or(value, path, "parity", "none"));
    if (*parity == "none") {
      ep.parity = 'N';
    } else if (*parity == "even") {
      ep.parity = 'E';
    } else if (*parity == "odd") {
      ep.parity = 'O';
    } else {
      return config_error(join_path(path, "parity"),
                          "unknown parity '" + *parity + "' (expected none, even, odd)");
    }
    FOGBENCH_TRY(data_bits, detail::get_int_or(value, path, "data_bits", 7, 8, 8));
    ep.data_bits = static_cast<int>(*data_bits);
    FOGBENCH_TRY(stop_bits, detail::get_int_or(value, path, "stop_bits", 1, 2, 1));
    ep.stop_bits = static_cast<int>(*stop_bits);
    for (auto k : {"host", "port"}) {
      if (value.contains(k)) return config_error(join_path(path, k), "only for transport 'tcp'");
    }
  } else {
    return config_error(join_path(path, "transport"),
                        "unknown transport '" + *transport + "' (expected " +
                            (serial_allowed ? "tcp, serial)" : "tcp)"));
  }
  FOGBENCH_TRY(timeout, detail::get_int_or(value, path, "response_timeout_ms", 1, 60000, 1000));
  ep.response_timeout_ms = static_cast<int>(*timeout);
  if (auto it = value.find("backoff"); it != value.end()) {
    FOGBENCH_TRY(backoff, parse_backoff(*it, join_path(path, "backoff"), ep.backoff));
    ep.backoff = *backoff;
  }
  return ep;
}

Result<ChamberConfig> parse_chamber_config(const json& value, const std::string& path,
                                           const std::filesystem::path& map_dir) {
  if (auto ok = detail::expect_object(value, path); !ok) return std::unexpected(ok.error());
  ChamberConfig cfg;
  // No "kind": the Modbus controller, as every configuration before kinds existed.
  FOGBENCH_TRY(kind_name, detail::get_string_or(value, path, "kind", "modbus"));
  const ChamberKind* kind = find_chamber_kind(*kind_name);
  if (kind == nullptr) {
    return config_error(join_path(path, "kind"), "unknown chamber kind '" + *kind_name +
                                                     "' (known: " + known_chamber_kinds() + ")");
  }
  cfg.kind = std::string(kind->name);
  std::vector<std::string_view> keys{"kind", "pv_limits_c", "setpoint_limits_c"};
  keys.insert(keys.end(), kind->fields.begin(), kind->fields.end());
  if (auto ok = detail::expect_known_keys(value, path, keys); !ok) return std::unexpected(ok.error());
  if (auto ok = kind->parse(value, path, map_dir, cfg); !ok) return std::unexpected(ok.error());
  FOGBENCH_TRY(pv, parse_limits(value, path, "pv_limits_c", cfg.pv_limits_c));
  cfg.pv_limits_c = *pv;
  FOGBENCH_TRY(sp, parse_limits(value, path, "setpoint_limits_c", cfg.setpoint_limits_c));
  cfg.setpoint_limits_c = *sp;
  return cfg;
}

Result<GyroChannelConfig> parse_gyro_channel(const json& value, const std::string& path) {
  if (auto ok = detail::expect_object(value, path); !ok) return std::unexpected(ok.error());
  if (auto ok = detail::expect_known_keys(
          value, path,
          {"node_id", "axes", "mode", "scale_dph_per_count", "scale_deg_per_count", "frame_rate_hz", "startup_flag"});
      !ok) {
    return std::unexpected(ok.error());
  }
  GyroChannelConfig g;
  FOGBENCH_TRY(node, detail::get_int(value, path, "node_id", 1, 2047));
  g.node_id = static_cast<std::uint16_t>(*node);
  // A three-axis unit's axis k sends on node_id + k (docs/drivers.md "Three-axis units").
  FOGBENCH_TRY(axes, detail::get_int_or(value, path, "axes", 1, 3, 1));
  if (*axes == 2) return config_error(join_path(path, "axes"), "expected 1 or 3 (a gyro unit has one axis or three)");
  g.axes = static_cast<std::uint8_t>(*axes);
  if (g.node_id + g.axes - 1 > 2047) {
    return config_error(join_path(path, "node_id"), std::to_string(g.node_id) + " with " + std::to_string(g.axes) +
                                                        " axes needs ids up to " + std::to_string(g.node_id + g.axes - 1) +
                                                        " (axis k sends on node_id + k; standard ids end at 2047)");
  }
  if (value.contains("startup_flag")) {
    if (!value["startup_flag"].is_boolean()) return config_error(join_path(path, "startup_flag"), "expected true or false");
    g.startup_flag = value["startup_flag"].get<bool>();
  }
  FOGBENCH_TRY(mode, detail::get_string_or(value, path, "mode", "rate"));
  auto nonzero = [&](std::string_view key) -> Result<double> {
    FOGBENCH_TRY(v, detail::get_number(value, path, key));
    if (*v == 0.0) return config_error(join_path(path, key), "must not be 0");
    return *v;
  };
  auto forbid = [&](std::string_view key, std::string_view mode_name) -> Result<void> {
    if (value.contains(key)) {
      return config_error(join_path(path, key), "not used in mode '" + std::string(mode_name) + "'");
    }
    return {};
  };
  if (*mode == "rate") {
    g.mode = GyroMode::rate;
    FOGBENCH_TRY(scale, nonzero("scale_dph_per_count"));
    g.scale_dph_per_count = *scale;
    if (auto ok = forbid("scale_deg_per_count", "rate"); !ok) return std::unexpected(ok.error());
    if (auto ok = forbid("frame_rate_hz", "rate"); !ok) return std::unexpected(ok.error());
  } else if (*mode == "increment") {
    g.mode = GyroMode::increment;
    FOGBENCH_TRY(scale, nonzero("scale_deg_per_count"));
    g.scale_deg_per_count = *scale;
    FOGBENCH_TRY(rate, detail::get_number(value, path, "frame_rate_hz"));
    if (*rate <= 0.0) return config_error(join_path(path, "frame_rate_hz"), "must be positive");
    g.frame_rate_hz = *rate;
    if (auto ok = forbid("scale_dph_per_count", "increment"); !ok) {
      return std::unexpected(ok.error());
    }
  } else {
    return config_error(join_path(path, "mode"),
                        "unknown mode '" + *mode + "' (expected rate, increment)");
  }
  return g;
}

std::string check_slot_name(std::string_view name) {
  if (name.empty()) return "must not be empty";
  if (name.size() > kMaxSlotBytes)
    return "longer than " + std::to_string(kMaxSlotBytes) + " characters (" + std::to_string(name.size()) + ")";
  for (char c : name) {
    const bool ok = (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_' || c == '-';
    if (!ok) return "'" + std::string(name) + "': only letters, digits, '_' and '-'";
  }
  return {};
}

std::string default_slot_name(std::size_t index) {
  std::string name;
  for (std::size_t n = index + 1; n > 0; n = (n - 1) / 26) name.insert(name.begin(), static_cast<char>('A' + (n - 1) % 26));
  return name;
}

Result<UnitConfig> parse_unit_config(const json& value, const std::string& path, std::size_t index) {
  if (auto ok = detail::expect_object(value, path); !ok) return std::unexpected(ok.error());
  // "gyro_line" (a serial line of the unit's own) is read by parse_drivers_config, which knows
  // the directory its frame file is named against.
  if (auto ok = detail::expect_known_keys(value, path, {"slot", "serial", "gyro", "thermistors", "gyro_line"}); !ok) {
    return std::unexpected(ok.error());
  }
  UnitConfig unit;
  unit.slot = default_slot_name(index);
  if (value.contains("slot")) {
    FOGBENCH_TRY(slot, detail::get_string(value, path, "slot"));
    if (auto why = check_slot_name(*slot); !why.empty()) return config_error(join_path(path, "slot"), why);
    unit.slot = *slot;
  }
  if (value.contains("serial")) {
    FOGBENCH_TRY(serial, detail::get_string(value, path, "serial"));
    if (serial->empty()) return config_error(join_path(path, "serial"), "must not be empty (leave it out for no default)");
    unit.serial = *serial;
  }
  const auto gp = join_path(path, "gyro");
  if (!value.contains("gyro")) return config_error(gp, "missing (expected an object)");
  FOGBENCH_TRY(gyro, parse_gyro_channel(value["gyro"], gp));
  unit.gyro = *gyro;

  const auto tp = join_path(path, "thermistors");
  auto th = value.find("thermistors");
  if (th == value.end()) return config_error(tp, "missing (expected {\"t1\": ..., \"t2\": ...})");
  if (auto ok = detail::expect_object(*th, tp); !ok) return std::unexpected(ok.error());
  if (auto ok = detail::expect_known_keys(*th, tp, {"t1", "t2", "x", "y", "z"}); !ok) {
    return std::unexpected(ok.error());
  }
  // A pair of channels {t1, t2} at `at`, both required.
  auto pair_of = [](const json& obj, const std::string& at, ThermistorChannelConfig& t1, ThermistorChannelConfig& t2) -> Result<void> {
    for (auto [key, target] : {std::pair{"t1", &t1}, std::pair{"t2", &t2}}) {
      const auto cp = join_path(at, key);
      if (!obj.contains(key)) return config_error(cp, "missing (expected an object)");
      FOGBENCH_TRY(ch, parse_thermistor_channel(obj[key], cp));
      *target = *ch;
    }
    return {};
  };
  const bool per_axis = th->contains("x") || th->contains("y") || th->contains("z");
  if (!per_axis) {
    if (auto ok = pair_of(*th, tp, unit.t1, unit.t2); !ok) return std::unexpected(ok.error());
    return unit;
  }
  // Per axis: each of x, y and z names its own coil's two channels.
  for (auto key : {"t1", "t2"})
    if (th->contains(key))
      return config_error(join_path(tp, key), "beside per-axis thermistors (x, y, z): give each axis its {\"t1\", \"t2\"} "
                                               "(x's are the unit's), or only t1 and t2 for thermistors the axes share");
  if (unit.gyro.axes != 3)
    return config_error(tp, "per-axis thermistors (x, y, z) need a three-axis gyro (gyro.axes 3); this unit's has " +
                                std::to_string(unit.gyro.axes));
  unit.axis_thermistors.resize(2);
  for (std::size_t k = 0; k < 3; ++k) {
    const char* axis = k == 0 ? "x" : k == 1 ? "y" : "z";
    const auto ap = join_path(tp, axis);
    if (!th->contains(axis))
      return config_error(ap, std::string("missing: a three-axis unit's thermistors per axis name every axis, x, y and z (axis ") + axis +
                                  " has none here); or give t1 and t2 alone for thermistors the axes share");
    const json& a = (*th)[axis];
    if (auto ok = detail::expect_object(a, ap); !ok) return std::unexpected(ok.error());
    if (auto ok = detail::expect_known_keys(a, ap, {"t1", "t2"}); !ok) return std::unexpected(ok.error());
    auto& t1 = k == 0 ? unit.t1 : unit.axis_thermistors[k - 1][0];
    auto& t2 = k == 0 ? unit.t2 : unit.axis_thermistors[k - 1][1];
    if (auto ok = pair_of(a, ap, t1, t2); !ok) return std::unexpected(ok.error());
  }
  return unit;
}

namespace {

// A frame layout given inline or as a file named against `map_dir`: the layout and the file.
Result<std::pair<serial::FrameFormat, std::string>> load_frame(const json& v, const std::string& fp,
                                                               const std::filesystem::path& map_dir) {
  if (v.is_string()) {
    std::filesystem::path file = v.get<std::string>();
    if (file.is_relative()) file = map_dir / file;
    std::ifstream in(file);
    if (!in) return config_error(fp, "cannot open '" + file.string() + "'");
    const json doc = json::parse(in, nullptr, false);
    if (doc.is_discarded()) return config_error(fp, "'" + file.string() + "' is not valid JSON");
    FOGBENCH_TRY(frame, serial::parse_frame_format(doc, file.filename().string()));
    return std::pair{*frame, file.string()};
  }
  FOGBENCH_TRY(frame, serial::parse_frame_format(v, fp));
  return std::pair{*frame, std::string()};
}

// A serial transport string whose framing can carry the layout (7 data bits drop bit 7).
Result<TransportSpec> check_line_framing(const std::string& transport, const serial::FrameFormat& frame,
                                         const std::string& tp) {
  auto spec = parse_transport_spec(transport);
  if (!spec) {
    // parse_transport_spec names gyro_bus.transport: say where this string is.
    std::string why = spec.error().message;
    if (why.starts_with("gyro_bus.transport: ")) why = why.substr(20);
    return config_error(tp, why);
  }
  if (spec->framing.data_bits == 7) {
    for (const auto byte : frame.sync) {
      if (byte >= 0x80) {
        return config_error(tp, "framing " + spec->framing.to_string() +
                                    ": 7 data bits cannot carry the frame's sync word (a byte >= 0x80); a binary frame needs 8");
      }
    }
  }
  return *spec;
}

}  // namespace

Result<DriversConfig> parse_drivers_config(const json& value, const std::filesystem::path& map_dir,
                                           const std::string& path) {
  if (auto ok = detail::expect_object(value, path); !ok) return std::unexpected(ok.error());
  if (auto ok = detail::expect_known_keys(value, path,
                                          {"chamber", "thermistors", "gyro_bus", "units"});
      !ok) {
    return std::unexpected(ok.error());
  }
  DriversConfig cfg;
  for (auto key : {"chamber", "thermistors", "gyro_bus", "units"}) {
    if (!value.contains(key)) return config_error(join_path(path, key), "missing");
  }
  FOGBENCH_TRY(chamber, parse_chamber_config(value["chamber"], join_path(path, "chamber"), map_dir));
  cfg.chamber = std::move(*chamber);

  {
    const auto tp = join_path(path, "thermistors");
    const json& t = value["thermistors"];
    if (auto ok = detail::expect_object(t, tp); !ok) return std::unexpected(ok.error());
    if (auto ok = detail::expect_known_keys(t, tp, {"modbus"}); !ok) return std::unexpected(ok.error());
    if (!t.contains("modbus")) return config_error(join_path(tp, "modbus"), "missing (expected an object)");
    FOGBENCH_TRY(modbus, parse_modbus_endpoint(t["modbus"], join_path(tp, "modbus")));
    cfg.thermistors.modbus = *modbus;
  }
  {
    const auto bp = join_path(path, "gyro_bus");
    const json& b = value["gyro_bus"];
    if (auto ok = detail::expect_object(b, bp); !ok) return std::unexpected(ok.error());
    if (auto ok = detail::expect_known_keys(b, bp, {"transport", "frame"}); !ok) return std::unexpected(ok.error());
    std::string transport;
    if (b.contains("transport")) {
      FOGBENCH_TRY(t, detail::get_string(b, bp, "transport"));
      transport = *t;
    }
    cfg.gyro_bus.transport = transport;
    const auto fp = join_path(bp, "frame");
    const bool is_serial = transport.starts_with("serial:");
    if (!is_serial && b.contains("frame")) {
      return config_error(fp, "only a serial: transport has a frame layout");
    }
    if (is_serial) {
      auto frame_it = b.find("frame");
      if (frame_it == b.end()) {
        return config_error(fp, "missing (a serial: transport needs the gyro's frame layout: a file name or an object)");
      }
      FOGBENCH_TRY(frame, load_frame(*frame_it, fp, map_dir));
      cfg.gyro_bus.frame = frame->first;
      cfg.gyro_bus.frame_file = frame->second;
      if (auto ok = check_line_framing(transport, *cfg.gyro_bus.frame, join_path(bp, "transport")); !ok) {
        return std::unexpected(ok.error());
      }
    }
  }

  const auto up = join_path(path, "units");
  const json& units = value["units"];
  if (!units.is_array() || units.empty()) return config_error(up, "expected a non-empty array");
  std::map<std::string, std::size_t> serials, slots;
  std::map<int, std::pair<std::size_t, std::uint8_t>> node_ids;  // CAN id -> unit index, axis
  struct Placed {
    std::string path;
    RegisterSpec reg;
  };
  std::vector<Placed> channels;
  for (std::size_t i = 0; i < units.size(); ++i) {
    const auto p = index_path(up, i);
    FOGBENCH_TRY(unit, parse_unit_config(units[i], p, i));
    if (auto [it, fresh] = slots.emplace(unit->slot, i); !fresh) {
      return config_error(join_path(p, "slot"), "'" + unit->slot + "' is already the slot of " +
                                                    index_path(up, it->second) +
                                                    (units[i].contains("slot") ? "" : " (named by its index)"));
    }
    if (auto [it, fresh] = serials.emplace(unit->serial, i); !unit->serial.empty() && !fresh) {
      return config_error(join_path(p, "serial"), "'" + unit->serial + "' is already used by " +
                                                      index_path(up, it->second));
    }
    // Every axis's id (node_id + axis) belongs to one unit's axis only.
    for (std::uint8_t k = 0; k < unit->gyro.axes; ++k) {
      const int id = unit->gyro.axis_id(k);
      if (auto [it, fresh] = node_ids.emplace(id, std::pair{i, k}); !fresh) {
        const auto [other, other_axis] = it->second;
        const auto& o = cfg.units[other].gyro;
        if (unit->gyro.axes == 1 && o.axes == 1) {
          return config_error(join_path(join_path(p, "gyro"), "node_id"),
                              std::to_string(id) + " is already used by " + index_path(up, other));
        }
        return config_error(join_path(join_path(p, "gyro"), "node_id"),
                            std::to_string(unit->gyro.node_id) + ": the id " + std::to_string(id) + " of its axis " +
                                std::to_string(k) + " is already the id of " + index_path(up, other) + "'s axis " +
                                std::to_string(other_axis) +
                                " (a three-axis unit sends on node_id, node_id + 1 and node_id + 2)");
      }
    }
    // Every channel, per axis too, on registers of its own.
    std::vector<std::pair<std::string, const ThermistorChannelConfig*>> unit_channels;
    const auto thp = join_path(p, "thermistors");
    const std::string xp = unit->has_axis_thermistors() ? join_path(thp, "x") : thp;
    unit_channels.emplace_back(join_path(xp, "t1"), &unit->t1);
    unit_channels.emplace_back(join_path(xp, "t2"), &unit->t2);
    for (std::size_t k = 0; k < unit->axis_thermistors.size(); ++k) {
      const auto ap = join_path(thp, k == 0 ? "y" : "z");
      unit_channels.emplace_back(join_path(ap, "t1"), &unit->axis_thermistors[k][0]);
      unit_channels.emplace_back(join_path(ap, "t2"), &unit->axis_thermistors[k][1]);
    }
    for (const auto& [cp, ch] : unit_channels) {
      for (const auto& other : channels) {
        const RegisterSpec& a = ch->reg;
        const RegisterSpec& b = other.reg;
        if (a.function == b.function && a.address < b.address + b.width() &&
            b.address < a.address + a.width()) {
          return config_error(join_path(cp, "address"), a.describe() + " overlaps " + other.path +
                                                            " (" + b.describe() + ")");
        }
      }
      channels.push_back({cp, ch->reg});
    }
    if (units[i].contains("gyro_line")) {
      const auto lp = join_path(p, "gyro_line");
      const json& l = units[i]["gyro_line"];
      if (auto ok = detail::expect_object(l, lp); !ok) return std::unexpected(ok.error());
      if (auto ok = detail::expect_known_keys(l, lp, {"transport", "frame"}); !ok) return std::unexpected(ok.error());
      FOGBENCH_TRY(line_transport, detail::get_string(l, lp, "transport"));
      const auto ltp = join_path(lp, "transport");
      if (!line_transport->starts_with("serial:")) {
        return config_error(ltp, "expected serial:DEVICE[?baud=N][&framing=8N1] (a unit's own line is a serial one; "
                                 "CAN units share gyro_bus.transport)");
      }
      if (!l.contains("frame")) {
        return config_error(join_path(lp, "frame"), "missing (the gyro's frame layout: a file name or an object)");
      }
      FOGBENCH_TRY(frame, load_frame(l["frame"], join_path(lp, "frame"), map_dir));
      FOGBENCH_TRY(spec, check_line_framing(*line_transport, frame->first, ltp));
      if (unit->gyro.mode != GyroMode::rate) {
        return config_error(join_path(join_path(p, "gyro"), "mode"), "a serial gyro's frames carry a rate: expected \"rate\"");
      }
      if (unit->gyro.axes != 1) {
        return config_error(join_path(join_path(p, "gyro"), "axes"), "a serial gyro's frame carries one axis: expected 1 (three-axis units are read on CAN)");
      }
      for (const auto& other : cfg.gyro_bus.lines) {
        if (parse_transport_spec(other.transport)->target == spec->target) {
          return config_error(ltp, "device '" + spec->target + "' is already the line of " + other.key);
        }
      }
      if (auto bus_spec = parse_transport_spec(cfg.gyro_bus.transport);
          bus_spec && bus_spec->kind == TransportSpec::Kind::serial) {
        return config_error(lp, "gyro_bus.transport is already a serial line (one gyro): with units on lines of "
                                "their own, gyro_bus.transport is the bus of the others (can:, unix:) or left out");
      }
      cfg.gyro_bus.lines.push_back({unit->gyro.node_id, *line_transport, frame->first, frame->second, lp});
    }
    cfg.units.push_back(std::move(*unit));
  }
  if (cfg.gyro_bus.transport.empty() && cfg.gyro_bus.lines.size() != cfg.units.size()) {
    for (std::size_t i = 0; i < cfg.units.size(); ++i) {
      if (!units[i].contains("gyro_line")) {
        return config_error(join_path(join_path(path, "gyro_bus"), "transport"),
                            "missing (" + index_path(up, i) + " has no gyro_line: it is read on the bus)");
      }
    }
  }
  if (cfg.gyro_bus.frame && cfg.units.size() != 1) {
    return config_error(join_path(join_path(path, "gyro_bus"), "transport"),
                        "a serial line carries one gyro's frames, but there are " +
                            std::to_string(cfg.units.size()) + " units (give each serial gyro a gyro_line of its own, and gyro_bus a CAN transport for the others)");
  }
  if (cfg.gyro_bus.frame && cfg.units[0].gyro.mode != GyroMode::rate) {
    return config_error(join_path(index_path(up, 0), "gyro.mode"),
                        "a serial gyro's frames carry a rate: expected \"rate\"");
  }
  if (cfg.gyro_bus.frame && cfg.units[0].gyro.axes != 1) {
    return config_error(join_path(index_path(up, 0), "gyro.axes"),
                        "a serial gyro's frame carries one axis: expected 1 (three-axis units are read on CAN)");
  }
  return cfg;
}

}  // namespace fogbench::drivers
