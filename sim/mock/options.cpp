// Options to configuration; see options.hpp. The --config file:
//   {"chamber": {"air_tau_s": 60, "max_rate_c_per_min": 5, "air_noise_c": 0.02},
//    "units": [{"serial": "SIM-0001", "frame_rate_hz": 100, "effects": "0.05*T1",
//               "coil": {"model": "distributed", "wall_tau_s": 150, "core_tau_s": 40, "t_noise_c": 0.005,
//                        "layers": 8, "inner_radius_mm": 35, "outer_radius_mm": 50, "winding_tau_s": 200,
//                        "film_tau_s": 300, "hub_capacity": 0.6, "mount_tau_s": 600, "contact_tau_s": 120,
//                        "t1_at": "inner", "t2_at": "outer", "shupe_dph_per_c_per_min": -5.5,
//                        "stress_dph_per_c": -0.6, "absolute_dph_per_c": 0.01},
//               "gyro": {"mu0_dph": -8.097, "terms": "...", "ar": [-0.005, -0.04],
//                        "sigma_a_dph": 0.146, "outlier_rate_per_s": 2e-4,
//                        "outlier_dph": 2.5, "tref_c": 20}}]}
#include "options.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <fstream>
#include <random>
#include <set>

#include "faults.hpp"
#include "fogbench/drivers/known_fields.hpp"

namespace fogbench::mock {

using nlohmann::json;

namespace {

std::string trim(std::string s) {
  const auto b = s.find_first_not_of(" \t");
  const auto e = s.find_last_not_of(" \t");
  return b == std::string::npos ? std::string() : s.substr(b, e - b + 1);
}

// An object with only the fields in `known`, listed in alphabetical order when one is not: the
// check every file of fogbench shares (drivers/known_fields.hpp). `path` starts with the --config
// file's name ("bench.json: units[0].coil"); `file` is set for the file's top level instead, said
// before the field ("bench.json: colour: unknown field ...").
std::expected<void, std::string> known_keys(const json& j, const std::string& path, const std::set<std::string_view>& known,
                                            const std::string& file = {}) {
  if (!j.is_object()) return std::unexpected((file.empty() ? path : file) + ": expected an object");
  const std::vector<std::string_view> sorted(known.begin(), known.end());
  if (auto refusal = drivers::unknown_field(j, path, sorted)) {
    return std::unexpected(file.empty() ? *refusal : file + ": " + *refusal);
  }
  return {};
}

// Reads an optional number into `out`; `positive` refuses zero and below.
std::expected<void, std::string> number(const json& j, const std::string& path, const char* key, double& out,
                                        bool positive = false) {
  if (!j.contains(key)) return {};
  const auto& v = j[key];
  if (!v.is_number() || !std::isfinite(v.get<double>()) || (positive && !(v.get<double>() > 0))) {
    return std::unexpected(path + "." + key + ": expected a " + (positive ? "positive " : "") + "number (got " + v.dump() + ")");
  }
  out = v.get<double>();
  return {};
}

std::expected<void, std::string> read_unit(const json& j, const std::string& path, sim::UnitParams& p, int& frame_rate_hz,
                                           Warmup& warmup) {
  if (auto ok = known_keys(j, path, {"serial", "frame_rate_hz", "effects", "coil", "gyro", "warmup"}); !ok) return ok;
  if (j.contains("warmup")) {
    const auto& w = j["warmup"];
    const auto wp = path + ".warmup";
    if (auto ok = known_keys(w, wp, {"dph", "tau_s"}); !ok) return ok;
    for (auto ok : {number(w, wp, "dph", warmup.dph), number(w, wp, "tau_s", warmup.tau_s, true)}) {
      if (!ok) return ok;
    }
  }
  if (j.contains("serial")) {
    if (!j["serial"].is_string() || j["serial"].get<std::string>().empty()) return std::unexpected(path + ".serial: expected a non-empty string");
    p.serial = j["serial"].get<std::string>();
  }
  if (j.contains("frame_rate_hz")) {
    const auto& v = j["frame_rate_hz"];
    if (!v.is_number_integer() || v.get<int>() < 1 || v.get<int>() > max_frame_rate_hz) {
      return std::unexpected(path + ".frame_rate_hz: expected an integer 1.." + std::to_string(max_frame_rate_hz));
    }
    frame_rate_hz = v.get<int>();
  }
  if (j.contains("effects")) {
    if (!j["effects"].is_string()) return std::unexpected(path + ".effects: expected a string in the term language");
    p.effects = j["effects"].get<std::string>();
  }
  if (j.contains("coil")) {
    const auto& c = j["coil"];
    const auto cp = path + ".coil";
    if (auto ok = known_keys(c, cp, {"model", "wall_tau_s", "core_tau_s", "t_noise_c", "layers", "inner_radius_mm", "outer_radius_mm",
                                      "winding_tau_s", "film_tau_s", "hub_capacity", "mount_tau_s", "contact_tau_s", "t1_at", "t2_at",
                                      "shupe_dph_per_c_per_min", "stress_dph_per_c", "absolute_dph_per_c"});
        !ok)
      return ok;
    auto& d = p.coil.distributed;
    double layers = d.layers;
    for (auto ok : {number(c, cp, "wall_tau_s", p.coil.wall_tau_s, true), number(c, cp, "core_tau_s", p.coil.core_tau_s, true),
                    number(c, cp, "t_noise_c", p.coil.t_noise_c), number(c, cp, "layers", layers, true),
                    number(c, cp, "inner_radius_mm", d.inner_radius_mm, true), number(c, cp, "outer_radius_mm", d.outer_radius_mm, true),
                    number(c, cp, "winding_tau_s", d.winding_tau_s, true), number(c, cp, "film_tau_s", d.film_tau_s, true),
                    number(c, cp, "hub_capacity", d.hub_capacity, true), number(c, cp, "mount_tau_s", d.mount_tau_s, true),
                    number(c, cp, "contact_tau_s", d.contact_tau_s, true), number(c, cp, "shupe_dph_per_c_per_min", d.shupe_dph_per_c_per_min),
                    number(c, cp, "stress_dph_per_c", d.stress_dph_per_c), number(c, cp, "absolute_dph_per_c", d.absolute_dph_per_c)}) {
      if (!ok) return ok;
    }
    if (layers != std::floor(layers)) return std::unexpected(cp + ".layers: expected an integer");
    d.layers = static_cast<int>(std::min(layers, 1000.0));
    for (auto [key, out] : {std::pair{"t1_at", &d.t1_at}, std::pair{"t2_at", &d.t2_at}}) {
      if (!c.contains(key)) continue;
      auto pl = c[key].is_string() ? sim::parse_placement(c[key].get<std::string>()) : std::unexpected(std::string("expected a string"));
      if (!pl) return std::unexpected(cp + "." + key + ": " + pl.error());
      *out = *pl;
    }
    if (c.contains("model")) {
      auto m = c["model"].is_string() ? sim::parse_coil_model(c["model"].get<std::string>()) : std::unexpected(std::string("expected a string"));
      if (!m) return std::unexpected(cp + ".model: " + m.error());
      p.coil.model = *m;
    }
    if (auto ok = d.validate(); !ok) return std::unexpected(cp + "." + ok.error());
  }
  if (j.contains("gyro")) {
    const auto& g = j["gyro"];
    const auto gp = path + ".gyro";
    if (auto ok = known_keys(g, gp, {"mu0_dph", "terms", "ar", "sigma_a_dph", "outlier_rate_per_s", "outlier_dph", "tref_c"}); !ok) return ok;
    for (auto ok : {number(g, gp, "mu0_dph", p.gyro.mu0_dph), number(g, gp, "sigma_a_dph", p.gyro.sigma_a_dph),
                    number(g, gp, "outlier_rate_per_s", p.gyro.outlier_rate_per_s), number(g, gp, "outlier_dph", p.gyro.outlier_dph),
                    number(g, gp, "tref_c", p.gyro.tref_c)}) {
      if (!ok) return ok;
    }
    if (g.contains("terms")) {
      if (!g["terms"].is_string()) return std::unexpected(gp + ".terms: expected a string in the term language");
      p.gyro.terms = g["terms"].get<std::string>();
    }
    if (g.contains("ar")) {
      if (!g["ar"].is_array()) return std::unexpected(gp + ".ar: expected an array of numbers");
      p.gyro.ar.clear();
      for (const auto& k : g["ar"]) {
        if (!k.is_number()) return std::unexpected(gp + ".ar: expected an array of numbers");
        p.gyro.ar.push_back(k.get<double>());
      }
    }
    if (p.gyro.sigma_a_dph < 0 || p.gyro.outlier_rate_per_s < 0 || p.gyro.outlier_rate_per_s > 1) {
      return std::unexpected(gp + ": sigma_a_dph must be >= 0 and outlier_rate_per_s in 0..1");
    }
  }
  return {};
}

}  // namespace

std::string join_effects(const std::vector<std::string>& effects) {
  std::string out;
  for (const auto& raw : effects) {
    const auto e = trim(raw);
    if (e.empty()) continue;
    if (out.empty()) out = e;
    else if (e.front() == '-') out += " - " + trim(e.substr(1));
    else if (e.front() == '+') out += " + " + trim(e.substr(1));
    else out += " + " + e;
  }
  return out;
}

std::expected<BenchConfig, std::string> make_bench_config(const Options& o) {
  BenchConfig cfg;
  auto port_ok = [](int p) { return p >= 0 && p <= 65535; };
  if (!port_ok(o.modbus_port)) return std::unexpected(std::string("--modbus-port: expected 0..65535"));
  if (!port_ok(o.thermistor_port)) return std::unexpected(std::string("--thermistor-port: expected 0..65535"));
  if (!o.gateway && o.modbus_port != 0 && o.modbus_port == o.thermistor_port) {
    return std::unexpected(std::string("--thermistor-port equals --modbus-port: use --gateway to serve both on one port"));
  }
  for (auto [name, id] : {std::pair{"--chamber-unit", o.chamber_unit}, std::pair{"--thermistor-unit", o.thermistor_unit}}) {
    if (id < 1 || id > 247) return std::unexpected(std::string(name) + ": expected a Modbus unit id 1..247");
  }
  if (o.gateway && o.chamber_unit == o.thermistor_unit) {
    return std::unexpected(std::string("--gateway needs different --chamber-unit and --thermistor-unit"));
  }
  if (!(o.time_scale > 0) || o.time_scale > 100000) return std::unexpected(std::string("--time-scale: expected a number in (0, 100000]"));
  if (!(o.duration_s >= 0)) return std::unexpected(std::string("--duration-s: expected a number >= 0"));
  const auto dialect = parse_chamber_dialect(o.chamber_dialect);
  if (!dialect) {
    return std::unexpected("--chamber-dialect: unknown dialect '" + o.chamber_dialect + "' (expected modbus, espec, simserv)");
  }
  if (o.gateway && *dialect != ChamberDialect::modbus) {
    return std::unexpected(std::string("--gateway needs --chamber-dialect modbus: an ASCII controller is no Modbus gateway"));
  }
  if (o.rate_table_port && (*o.rate_table_port < 0 || *o.rate_table_port > 65535)) {
    return std::unexpected("--rate-table-port: expected 0..65535 (got " + std::to_string(*o.rate_table_port) + ")");
  }
  cfg.rate_table_port = o.rate_table_port;
  if (o.paced && o.control.empty()) return std::unexpected(std::string("--paced needs --control: the clock is advanced through it"));
  if (!(o.frame_noise_dph >= 0)) return std::unexpected(std::string("--frame-noise-dph: expected a number >= 0"));
  if (o.axes != 1 && o.axes != 3) return std::unexpected("--axes: expected 1 or 3 (got " + std::to_string(o.axes) + ")");
  if (!(o.axis_bias_dph >= 0) || !std::isfinite(o.axis_bias_dph)) {
    return std::unexpected(std::string("--axis-bias-dph: expected a number >= 0"));
  }
  if (!o.axis_effects.empty() && o.axes != 3) {
    return std::unexpected(std::string("--axis-effect needs --axes 3 (a one-axis unit's drift is --effect)"));
  }
  if (o.axis_thermistors && o.axes != 3) {
    return std::unexpected(std::string("--axis-thermistors needs --axes 3 (a one-axis unit has one coil)"));
  }
  // Read by fogctl simulate's rule. x's own drift (one y and z do not share) and a term of
  // another axis's coil (T1y, ...) only with coils per axis.
  const auto axis_effects = sim::parse_axis_effects(o.axis_effects, o.axis_thermistors);
  if (!axis_effects) return std::unexpected(axis_effects.error());
  if (!axis_effects->text[0].empty() && !o.axis_thermistors) {
    return std::unexpected("--axis-effect x=" + axis_effects->text[0] +
                           ": without --axis-thermistors the mock bench gives y and z their own drift only, AXIS y or z (x's drift is "
                           "the unit's, which y and z share: --effect)");
  }
  if (!std::isfinite(o.warmup_dph)) return std::unexpected(std::string("--warmup-dph: expected a number"));
  if (!(o.warmup_tau_s > 0) || !std::isfinite(o.warmup_tau_s)) return std::unexpected(std::string("--warmup-tau-s: expected a positive number"));
  if (!std::isfinite(o.start_c) || o.start_c < min_start_c || o.start_c > max_start_c) {
    return std::unexpected("--start-c: expected " + std::to_string(static_cast<int>(min_start_c)) + ".." +
                           std::to_string(static_cast<int>(max_start_c)) + " degC");
  }
  const auto coil_model = sim::parse_coil_model(o.coil);
  if (!coil_model) return std::unexpected("--coil: " + coil_model.error());
  cfg.where.host = o.host;
  cfg.where.chamber_port = o.modbus_port;
  cfg.where.thermistor_port = o.gateway ? o.modbus_port : o.thermistor_port;
  cfg.where.chamber_unit = o.chamber_unit;
  cfg.where.thermistor_unit = o.thermistor_unit;
  cfg.where.can_socket = o.can_socket;
  if (o.serial_gyro.empty() != o.serial_frame.empty()) {
    return std::unexpected(std::string("--serial-gyro and --serial-frame go together (the link's path and the frame layout's file)"));
  }
  if (!o.serial_gyro.empty() && o.axes != 1) {
    return std::unexpected(std::string("--serial-gyro needs --axes 1: a serial gyro's frame carries one axis"));
  }
  if (!o.serial_gyro.empty()) {
    std::ifstream frame_in(o.serial_frame);
    if (!frame_in) return std::unexpected("--serial-frame: " + o.serial_frame + ": cannot open");
    const auto doc = nlohmann::json::parse(frame_in, nullptr, false);
    if (doc.is_discarded()) return std::unexpected("--serial-frame: " + o.serial_frame + ": not valid JSON");
    auto frame = drivers::serial::parse_frame_format(doc, "--serial-frame");
    if (!frame) return std::unexpected(frame.error().message);
    cfg.serial_gyro_link = o.serial_gyro;
    cfg.serial_frame = *frame;
    cfg.serial_frame_json = doc;
  }
  cfg.gateway = o.gateway;
  cfg.dialect = *dialect;
  cfg.control_path = o.control;
  cfg.time_scale = o.time_scale;
  cfg.duration_s = o.duration_s;
  cfg.paced = o.paced;
  cfg.frame_noise_dph = o.frame_noise_dph;
  cfg.startup_flag = !o.no_startup_flag;
  cfg.sim.seed = o.seed;
  cfg.sim.start_c = o.start_c;

  json file;
  if (!o.config_file.empty()) {
    std::ifstream in(o.config_file);
    if (!in) return std::unexpected(o.config_file + ": cannot open");
    try {
      file = json::parse(in);
    } catch (const json::exception& e) {
      return std::unexpected(o.config_file + ": " + e.what());
    }
    if (auto ok = known_keys(file, "", {"chamber", "units"}, o.config_file); !ok) return std::unexpected(ok.error());
    if (file.contains("chamber")) {
      const auto& c = file["chamber"];
      const auto cp = o.config_file + ": chamber";
      if (auto ok = known_keys(c, cp, {"air_tau_s", "max_rate_c_per_min", "air_noise_c"}); !ok) return std::unexpected(ok.error());
      for (auto ok : {number(c, cp, "air_tau_s", cfg.sim.chamber.air_tau_s, true),
                      number(c, cp, "max_rate_c_per_min", cfg.sim.chamber.max_rate_c_per_min, true),
                      number(c, cp, "air_noise_c", cfg.sim.chamber.air_noise_c)}) {
        if (!ok) return std::unexpected(ok.error());
      }
    }
    if (file.contains("units") && !file["units"].is_array()) return std::unexpected(o.config_file + ": units: expected an array");
  }
  const std::size_t from_file = file.contains("units") ? file["units"].size() : 0;
  if (o.units && from_file > 0 && static_cast<std::size_t>(*o.units) != from_file) {
    return std::unexpected("--units " + std::to_string(*o.units) + " but " + o.config_file + " describes " + std::to_string(from_file));
  }
  const std::size_t n = o.units ? static_cast<std::size_t>(*o.units) : (from_file > 0 ? from_file : 2);
  if (n < 1 || n > max_units) return std::unexpected("--units: expected 1.." + std::to_string(max_units));

  cfg.sim.units.clear();
  std::set<std::string> serials;
  // The y and z axes' biases: their own stream of the seed, so one-axis benches draw nothing.
  std::mt19937_64 bias_rng(o.seed ^ 0xA5A5F00DC0FFEE11ull);
  std::normal_distribution<double> bias(0.0, 1.0);
  for (std::size_t i = 0; i < n; ++i) {
    int rate = o.frame_rate_hz;
    auto layout = default_unit_layout(i, rate, o.axes, o.axis_thermistors);
    if (!layout) return std::unexpected("--frame-rate-hz: " + layout.error());
    for (std::size_t k = 1; k < layout->axis_bias_dph.size(); ++k) layout->axis_bias_dph[k] = o.axis_bias_dph * bias(bias_rng);
    sim::UnitParams p;
    p.serial = layout->serial;
    p.coil.model = *coil_model;
    Warmup warmup{o.warmup_dph, o.warmup_tau_s};
    if (i < from_file) {
      if (auto ok = read_unit(file["units"][i], o.config_file + ": units[" + std::to_string(i) + "]", p, rate, warmup); !ok) {
        return std::unexpected(ok.error());
      }
    }
    std::vector<std::string> effects = {p.effects};
    effects.insert(effects.end(), o.effects.begin(), o.effects.end());
    p.effects = join_effects(effects);
    if (auto law = sim::make_drift_law(p); !law) return std::unexpected("unit " + p.serial + ": " + law.error());
    p.axis_effects = {axis_effects->text[1], axis_effects->text[2]};
    if (o.axis_thermistors) {
      p.axis_coils = std::array{sim::deeper_in_housing(p.coil, 1), sim::deeper_in_housing(p.coil, 2)};
      p.x_effects = axis_effects->text[0];
    }
    if (!serials.insert(p.serial).second) return std::unexpected("two units have serial " + p.serial);
    layout->serial = p.serial;
    layout->frame_rate_hz = rate;
    cfg.units.push_back(*layout);
    cfg.sim.units.push_back(p);
    cfg.warmup.push_back(warmup);
  }

  auto map = load_served_map(o.map_file);
  if (!map) return std::unexpected("--map: " + map.error());
  cfg.map = std::move(*map);

  for (const auto& f : o.faults) {
    auto command = fault_json_from_cli(f);
    if (!command) return std::unexpected(command.error());
    std::vector<std::string> names;
    for (const auto& u : cfg.units) names.push_back(u.serial);
    if (auto parsed = parse_fault_command(*command, names); !parsed) return std::unexpected("--fault " + f + ": " + parsed.error());
    cfg.start_faults.push_back(*command);
  }
  return cfg;
}

}  // namespace fogbench::mock
