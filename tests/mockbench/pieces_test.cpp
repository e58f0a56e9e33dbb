// The mock bench's pure pieces, without processes or sockets: the served layout against the
// shipped example configuration, the thermistor encodings against the drivers' conversions,
// the frames of a second, fault commands in both forms, and the control protocol's dispatch
// (its framing: line_server_test.cpp).
#include <catch2/catch.hpp>

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <numeric>
#include <random>
#include <tuple>

#include "control.hpp"
#include "faults.hpp"
#include "fogbench/drivers/can_frame.hpp"
#include "fogbench/drivers/config.hpp"
#include "fogbench/drivers/sample_accumulator.hpp"
#include "fogbench/drivers/thermistor_conversion.hpp"
#include "frames.hpp"
#include "layout.hpp"
#include "options.hpp"

using namespace fogbench;
using namespace fogbench::mock;
using nlohmann::json;

namespace {

drivers::DriversConfig example() {
  std::ifstream in(FOGBENCH_SOURCE_DIR "/drivers/examples/mock-bench.json");
  REQUIRE(in);
  auto cfg = drivers::parse_drivers_config(json::parse(in), FOGBENCH_SOURCE_DIR "/drivers/maps");
  REQUIRE(cfg.has_value());
  return *cfg;
}

bool same_register(const drivers::RegisterSpec& a, const drivers::RegisterSpec& b) {
  return a.function == b.function && a.address == b.address && a.type == b.type &&
         a.word_order == b.word_order && a.scale == b.scale && a.offset == b.offset;
}

}  // namespace

TEST_CASE("the default layout serves what drivers/examples/mock-bench.json declares") {
  const auto ex = example();
  REQUIRE(ex.units.size() == 2);
  for (std::size_t i = 0; i < 2; ++i) {
    INFO("unit " << i);
    auto u = default_unit_layout(i, 100);
    REQUIRE(u.has_value());
    const auto& want = ex.units[i];
    CHECK(u->gyro.node_id == want.gyro.node_id);
    CHECK(u->gyro.mode == want.gyro.mode);
    CHECK(u->gyro.scale_dph_per_count == want.gyro.scale_dph_per_count);
    CHECK(u->gyro.scale_deg_per_count == want.gyro.scale_deg_per_count);
    CHECK(u->gyro.frame_rate_hz == want.gyro.frame_rate_hz);
    for (auto [got, exp] : {std::pair{&u->t1, &want.t1}, std::pair{&u->t2, &want.t2}}) {
      CHECK(same_register(got->reg, exp->reg));
      CHECK(got->kind == exp->kind);
      CHECK(got->open_circuit_raw == exp->open_circuit_raw);
      CHECK(got->coefficients.a == exp->coefficients.a);
      CHECK(got->max_ohm == exp->max_ohm);
    }
  }
  // The map served by default is the one the example names.
  auto served = load_served_map("");
  REQUIRE(served.has_value());
  CHECK(served->map.name == ex.chamber.map.name);
  CHECK(same_register(served->map.process_value, ex.chamber.map.process_value));
}

TEST_CASE("further units continue the pattern on registers of their own") {
  std::vector<UnitLayout> units;
  for (std::size_t i = 0; i < max_units; ++i) {
    auto u = default_unit_layout(i, 100);
    REQUIRE(u.has_value());
    units.push_back(*u);
  }
  CHECK_FALSE(default_unit_layout(max_units, 100).has_value());
  auto map = load_served_map("");
  REQUIRE(map.has_value());
  // parse_drivers_config refuses shared node ids, serials and thermistor registers.
  const auto cfg = drivers_config({.can_socket = "/tmp/x.sock"}, *map, units);
  auto parsed = drivers::parse_drivers_config(cfg, FOGBENCH_SOURCE_DIR "/drivers/maps");
  INFO((parsed ? std::string() : parsed.error().to_string()));
  REQUIRE(parsed.has_value());
  CHECK(parsed->units.size() == max_units);
  CHECK(parsed->units[31].gyro.node_id == 257 + 31);
}

TEST_CASE("thermistor readings encode to words the drivers convert back") {
  for (std::size_t i : {0u, 1u}) {
    auto u = default_unit_layout(i, 100);
    REQUIRE(u.has_value());
    // Inside the channels' default valid range, -60..150 degC (its very ends may round outside).
    for (double t : {-59.5, -40.0, 0.0, 20.0, 25.0, 85.0, 149.5}) {
      auto words = encode_thermistor(u->t1, t);
      REQUIRE(words.has_value());
      auto back = drivers::convert_thermistor(u->t1, *words, "unit T1");
      INFO("unit " << i << " at " << t << " degC");
      REQUIRE(back.has_value());
      // int16 centi-degrees round to 0.005 degC; a float32 resistance has 24 bits (6e-8
      // relative), about 3e-6 degC through an NTC's 4%/degC.
      CHECK(*back == Approx(t).margin(i == 0 ? 0.005 : 1e-4));
    }
    auto open = drivers::convert_thermistor(u->t2, encode_open_circuit(u->t2), "unit T2");
    REQUIRE_FALSE(open.has_value());
    CHECK(open.error().code == drivers::ErrorCode::open_circuit);
  }
}

TEST_CASE("the NTC resistance inverts the drivers' Steinhart-Hart equation") {
  const drivers::SteinhartHart sh{1.129148e-3, 2.34125e-4, 8.76741e-8};
  // 10 kohm at 25 degC is what these coefficients are made for.
  CHECK(ntc_resistance_ohm(sh, 25.0) == Approx(10000.0).epsilon(1e-3));
  for (double t = -80.0; t <= 200.0; t += 7.0) {
    CHECK(sh.temp_c(ntc_resistance_ohm(sh, t)) == Approx(t).margin(1e-9));
  }
  const drivers::SteinhartHart beta_only{1.129148e-3, 2.34125e-4, 0.0};
  CHECK(beta_only.temp_c(ntc_resistance_ohm(beta_only, 42.0)) == Approx(42.0).margin(1e-9));
}

TEST_CASE("a fault's command-line form becomes its JSON command") {
  auto j = fault_json_from_cli("stall_modbus=800,device=chamber");
  REQUIRE(j.has_value());
  CHECK(*j == json({{"cmd", "fault"}, {"name", "stall_modbus"}, {"on", true}, {"ms", 800}, {"device", "chamber"}}));
  j = fault_json_from_cli("open_thermistor=t2,unit=1");
  REQUIRE(j.has_value());
  CHECK((*j)["sensor"] == "t2");
  CHECK((*j)["unit"] == 1);
  j = fault_json_from_cli("lose_frames=0.25,unit=SIM-0002");
  REQUIRE(j.has_value());
  CHECK((*j)["fraction"] == 0.25);
  CHECK((*j)["unit"] == "SIM-0002");
  CHECK(fault_json_from_cli("freeze_pv")->at("name") == "freeze_pv");
  CHECK(fault_json_from_cli("freeze_pv=3").error() == "--fault freeze_pv takes no value");
  CHECK(fault_json_from_cli("nope").error() == "--fault: unknown fault 'nope'");
  CHECK(fault_json_from_cli("alarm,oops").error() == "--fault: expected KEY=VALUE, got 'oops'");
}

TEST_CASE("fault commands switch the state the bench reads, and are listed while active") {
  const std::vector<std::string> serials = {"SIM-0001", "SIM-0002"};
  FaultState state;
  state.units.resize(2);
  auto apply = [&](const json& j, double now = 100.0) {
    auto c = parse_fault_command(j, serials);
    INFO(j.dump());
    REQUIRE(c.has_value());
    apply_fault(state, *c, now);
  };
  apply({{"name", "stall_modbus"}, {"ms", 300}});
  CHECK(state.stall_ms == std::array<int, 2>{300, 300});
  apply({{"name", "stall_modbus"}, {"device", "chamber"}, {"on", false}});
  CHECK(state.stall_ms == std::array<int, 2>{0, 300});
  apply({{"name", "gyro_spike"}, {"unit", 1}, {"dph", 50}, {"duration_s", 20}}, 100.0);
  CHECK(state.units[1].spike_dph == 50);
  CHECK(state.units[1].spike_until_s == 120.0);  // seconds 100..119 spiked
  CHECK(state.units[0].spike_dph == 0);
  apply({{"name", "lose_burst"}, {"unit", "SIM-0001"}, {"count", 20}});
  apply({{"name", "lose_burst"}, {"unit", "SIM-0001"}, {"count", 5}});
  CHECK(state.units[0].lose_burst == 25);  // bursts add up
  apply({{"name", "open_thermistor"}, {"sensor", "t1"}});
  CHECK((state.units[0].open_t1 && state.units[1].open_t1 && !state.units[0].open_t2));

  const auto active = active_faults(state, serials, 110.0);
  CHECK(active.size() == 5);  // stall (thermistors), spike, burst, two open sensors
  CHECK(active_faults(state, serials, 120.0).size() == 4);  // the spike is over at 120 s

  CHECK(parse_fault_command({{"name", "gyro_spike"}, {"unit", 2}, {"dph", 1}}, serials).error() ==
        "gyro_spike: unit: expected an index 0..1 or a serial (got 2)");
  CHECK(parse_fault_command({{"name", "gyro_spike"}, {"unit", "FOG-9"}, {"dph", 1}}, serials).error() ==
        "gyro_spike: unit: no unit has serial \"FOG-9\"");
  CHECK(parse_fault_command({{"name", "corrupt_frames"}, {"fraction", 1.5}}, serials).error() ==
        "corrupt_frames: fraction: expected 0..1 (got 1.5)");
  // Switching off needs no parameter.
  CHECK(parse_fault_command({{"name", "stall_modbus"}, {"on", false}}, serials).has_value());
}

namespace {

struct FakeHandler : ControlHandler {
  std::vector<json> faults;
  bool stopped = false;
  std::expected<void, std::string> fault(const json& c) override {
    faults.push_back(c);
    if (c.value("name", "") == "bad") return std::unexpected(std::string("bad fault"));
    return {};
  }
  json status() override { return {{"time_s", 12.0}}; }
  void stop() override { stopped = true; }
  std::int64_t advanced_s = 0;
  std::expected<double, std::string> advance(std::int64_t seconds) override {
    advanced_s += seconds;
    return static_cast<double>(advanced_s);
  }
};

}  // namespace

TEST_CASE("control protocol: one reply line per request, errors as values") {
  FakeHandler h;
  CHECK(handle_line(R"({"cmd":"status"})", h) == R"({"ok":true,"time_s":12.0,"version":1})");
  CHECK(handle_line(R"({"cmd":"stop"})", h) == R"({"ok":true})");
  CHECK(h.stopped);

  CHECK(handle_line(R"({"cmd":"fault","name":"bad"})", h) == R"({"error":"bad fault","ok":false})");
  CHECK(json::parse(handle_line("{not json", h))["error"].get<std::string>().starts_with("not JSON"));
  CHECK(json::parse(handle_line(R"({"cmd":"reboot"})", h))["error"] == "unknown cmd 'reboot' (known: advance, fault, status, stop)");
  // advance: one second by default, or `seconds`; the reply carries the simulated time after it.
  CHECK(handle_line(R"({"cmd":"advance"})", h) == R"({"ok":true,"time_s":1.0})");
  CHECK(handle_line(R"({"cmd":"advance","seconds":4})", h) == R"({"ok":true,"time_s":5.0})");
  CHECK(json::parse(handle_line(R"({"cmd":"advance","seconds":0})", h))["error"] ==
        "advance: seconds: expected an integer 1..86400 (got 0)");
  CHECK(json::parse(handle_line(R"({"cmd":"advance","seconds":1.5})", h))["ok"] == false);
  CHECK(h.advanced_s == 5);  // the refused ones moved nothing
  CHECK(json::parse(handle_line(R"([1,2])", h))["ok"] == false);

  CHECK(json::parse(handle_line(std::string(max_control_line + 1, ' '), h))["error"] == "request longer than 4096 bytes");
}

TEST_CASE("options: effects join in the term language, and refusals name the option") {
  CHECK(join_effects({"0.05*T1", "-0.02*T2", "", "+ 1e-3*T1^2"}) == "0.05*T1 - 0.02*T2 + 1e-3*T1^2");
  Options o;
  o.effects = {"0.05*T1", "-0.02*T2"};
  auto cfg = make_bench_config(o);
  REQUIRE(cfg.has_value());
  CHECK(cfg->sim.units.size() == 2);
  CHECK(cfg->sim.units[1].effects == "0.05*T1 - 0.02*T2");
  o.effects = {"0.05*T9"};
  CHECK_FALSE(make_bench_config(o).has_value());
  o.effects.clear();
  o.units = 40;
  CHECK(make_bench_config(o).error() == "--units: expected 1..32");
  o.units.reset();
  o.faults = {"lose_frames=0.5,unit=7"};
  CHECK(make_bench_config(o).error().starts_with("--fault lose_frames=0.5,unit=7: lose_frames: unit:"));
}

TEST_CASE("options: a --config file sets per-unit parameters and refuses unknown fields") {
  char tmpl[] = "/tmp/fogbench-mockcfg-XXXXXX";
  REQUIRE(::mkdtemp(tmpl) != nullptr);
  const std::string file = std::string(tmpl) + "/bench.json";
  auto write = [&](const json& j) {
    std::ofstream out(file);
    out << j.dump();
  };
  write({{"chamber", {{"air_tau_s", 90}}},
         {"units", {{{"serial", "FOG-A"}, {"frame_rate_hz", 250}, {"effects", "0.1*T2"}},
                    json::object(),
                    {{"coil", {{"wall_tau_s", 300}}}, {"gyro", {{"mu0_dph", 1.5}, {"ar", {0.1}}}}}}}});
  Options o;
  o.config_file = file;
  o.effects = {"0.05*T1"};
  auto cfg = make_bench_config(o);
  INFO((cfg ? std::string() : cfg.error()));
  REQUIRE(cfg.has_value());
  REQUIRE(cfg->units.size() == 3);  // the file's count
  CHECK(cfg->sim.chamber.air_tau_s == 90);
  CHECK(cfg->units[0].serial == "FOG-A");
  CHECK(cfg->sim.units[0].serial == "FOG-A");
  CHECK(cfg->units[0].frame_rate_hz == 250);
  CHECK(cfg->units[1].frame_rate_hz == 100);
  CHECK(cfg->sim.units[0].effects == "0.1*T2 + 0.05*T1");
  CHECK(cfg->sim.units[2].effects == "0.05*T1");
  CHECK(cfg->sim.units[2].coil.wall_tau_s == 300);
  CHECK(cfg->sim.units[2].gyro.mu0_dph == 1.5);
  CHECK(cfg->sim.units[2].gyro.ar == std::vector<double>{0.1});
  CHECK(cfg->sim.units[0].coil.model == sim::CoilModel::distributed);  // --coil's default

  o.units = 2;
  CHECK(make_bench_config(o).error() == "--units 2 but " + file + " describes 3");
  o.units.reset();
  write({{"units", {{{"coil", {{"wal_tau_s", 300}}}}}}});
  CHECK(make_bench_config(o).error() ==
        file + ": units[0].coil.wal_tau_s: unknown field (known: absolute_dph_per_c, contact_tau_s, core_tau_s, film_tau_s, "
               "hub_capacity, inner_radius_mm, layers, model, mount_tau_s, outer_radius_mm, shupe_dph_per_c_per_min, "
               "stress_dph_per_c, t1_at, t2_at, t_noise_c, wall_tau_s, winding_tau_s)");
  // At the file's top level the file is named before the field, not joined to it as a path.
  write({{"chamber", {{"air_tau_s", 90}}}, {"colour", "blue"}});
  CHECK(make_bench_config(o).error() == file + ": colour: unknown field (known: chamber, units)");
  write({{"chamber", {{"air_tau_s", 90}, {"air_tau", 60}}}});
  CHECK(make_bench_config(o).error() ==
        file + ": chamber.air_tau: unknown field (known: air_noise_c, air_tau_s, max_rate_c_per_min)");
  // The distributed coil's parameters, its thermistors' places and the model per unit.
  write({{"units", {{{"coil", {{"model", "lumped"}, {"layers", 10}, {"t1_at", "middle"}, {"winding_tau_s", 150}}}}}}});
  auto coil = make_bench_config(o);
  REQUIRE(coil.has_value());
  CHECK(coil->sim.units[0].coil.model == sim::CoilModel::lumped);
  CHECK(coil->sim.units[0].coil.distributed.layers == 10);
  CHECK(coil->sim.units[0].coil.distributed.t1_at == sim::Placement::middle);
  CHECK(coil->sim.units[0].coil.distributed.winding_tau_s == 150);
  write({{"units", {{{"coil", {{"t2_at", "centre"}}}}}}});
  CHECK(make_bench_config(o).error() ==
        file + ": units[0].coil.t2_at: unknown thermistor placement 'centre' (known: hub, inner, middle, outer)");
  write({{"units", {{{"coil", {{"layers", 5}}}}}}});
  CHECK(make_bench_config(o).error() == file + ": units[0].coil.layers: expected 6..64");
  o.coil = "two-node";
  CHECK(make_bench_config(o).error() == "--coil: unknown coil model 'two-node' (known: distributed, lumped)");
  o.coil = "distributed";
  write({{"units", {{{"serial", "X"}}, {{"serial", "X"}}}}});
  CHECK(make_bench_config(o).error() == "two units have serial X");
  std::filesystem::remove_all(tmpl);
}

TEST_CASE("power faults: power_off for a while or until switched off, power_cycle as an action") {
  const std::vector<std::string> serials = {"SIM-0001", "SIM-0002"};
  FaultState state;
  state.units.assign(2, {});
  auto apply = [&](const json& j, double next_second_s) {
    auto c = parse_fault_command(j, serials);
    INFO(j.dump() << ": " << (c ? "" : c.error()));
    REQUIRE(c.has_value());
    apply_fault(state, *c, next_second_s);
  };
  // --fault power_off=600,unit=1 at start: SIM-0002 powers on 600 s into the session.
  auto cli = fault_json_from_cli("power_off=600,unit=1");
  REQUIRE(cli.has_value());
  CHECK(*cli == json({{"cmd", "fault"}, {"name", "power_off"}, {"on", true}, {"duration_s", 600}, {"unit", 1}}));
  apply(*cli, 0.0);
  CHECK(state.units[1].power_off_from_s == 0.0);
  CHECK(state.units[1].power_on_at_s == 600.0);
  CHECK(std::isinf(state.units[0].power_off_from_s));  // SIM-0001 untouched
  auto active = active_faults(state, serials, 10.0);
  REQUIRE(active.size() == 1);
  CHECK(active[0]["name"] == "power_off");
  CHECK(active[0]["until_s"] == 600.0);
  CHECK(active_faults(state, serials, 600.0).empty());  // on again

  // power_cycle: off from the next second for off_s (default 3 s).
  apply({{"name", "power_cycle"}, {"unit", "SIM-0001"}}, 100.0);
  CHECK(state.units[0].power_off_from_s == 100.0);
  CHECK(state.units[0].power_on_at_s == 100.0 + default_power_cycle_off_s);
  apply({{"name", "power_cycle"}, {"unit", 0}, {"off_s", 10}}, 200.0);
  CHECK(state.units[0].power_on_at_s == 210.0);

  // power_off without a duration lasts until switched off, from the next second.
  apply({{"name", "power_off"}, {"unit", 0}}, 300.0);
  CHECK(std::isinf(state.units[0].power_on_at_s));
  CHECK(active_faults(state, serials, 400.0)[0]["until_s"].is_null());
  apply({{"name", "power_off"}, {"unit", 0}, {"on", false}}, 400.0);
  CHECK(state.units[0].power_off_from_s == 300.0);
  CHECK(state.units[0].power_on_at_s == 400.0);
  active = active_faults(state, serials, 400.0);
  REQUIRE(active.size() == 1);  // SIM-0002 is still off until 600 s
  CHECK(active[0]["unit"] == 1);

  CHECK(parse_fault_command({{"name", "power_cycle"}, {"off_s", 0}}, serials).error() ==
        "power_cycle: off_s: expected 1e-09..1000000000 (got 0)");
  CHECK(parse_fault_command({{"name", "power_off"}, {"ms", 5}}, serials).error() ==
        "power_off.ms: unknown field (known: duration_s, on, unit)");
}

TEST_CASE("mock bench options --axes: 1 or 3, and not with a serial gyro", "[three_axis]") {
  fogbench::mock::Options o;
  o.axes = 2;
  auto cfg = fogbench::mock::make_bench_config(o);
  REQUIRE_FALSE(cfg.has_value());
  CHECK(cfg.error() == "--axes: expected 1 or 3 (got 2)");
  o.axes = 1;
  cfg = fogbench::mock::make_bench_config(o);
  REQUIRE(cfg.has_value());
  CHECK(cfg->units[1].gyro.node_id == 258);  // one-axis units: ids and biases as before
  CHECK(cfg->units[1].axis_bias_dph == std::vector<double>{0.0});
  o.axes = 3;
  cfg = fogbench::mock::make_bench_config(o);
  REQUIRE(cfg.has_value());
  CHECK(cfg->units[1].gyro.node_id == 261);
  CHECK(cfg->units[1].gyro.axes == 3);
  o.serial_gyro = "/tmp/x";
  o.serial_frame = "/tmp/y.json";
  cfg = fogbench::mock::make_bench_config(o);
  REQUIRE_FALSE(cfg.has_value());
  CHECK(cfg.error() == "--serial-gyro needs --axes 1: a serial gyro's frame carries one axis");
}

TEST_CASE("mock bench options --axis-effect: y or z of three-axis units, every unit, bad ones named", "[three_axis]") {
  fogbench::mock::Options o;
  o.axes = 3;
  o.axis_effects = {"y=1*T1", "z=-0.5*T1", "y=0.1*grad"};
  auto cfg = fogbench::mock::make_bench_config(o);
  REQUIRE(cfg.has_value());
  for (const auto& u : cfg->sim.units) {
    CHECK(u.axis_effects[0] == "1*T1 + 0.1*grad");
    CHECK(u.axis_effects[1] == "-0.5*T1");
    CHECK(u.effects.find("T1") == std::string::npos);  // x (the unit's own drift) has none of it
  }
  for (const auto& [axes, effect, says] :
       {std::tuple{1, "y=1*T1", "--axis-effect needs --axes 3"}, std::tuple{3, "x=1*T1", "AXIS y or z"},
        std::tuple{3, "1*T1", "expected AXIS=TERMS"}, std::tuple{3, "y=1*T9", "--axis-effect y=1*T9"},
        std::tuple{3, "z=1*T1@auto", "fixed lag"}, std::tuple{3, "y=1*T1x", "own coil thermistor"}}) {
    o.axes = axes;
    o.axis_effects = {effect};
    cfg = fogbench::mock::make_bench_config(o);
    INFO(effect);
    REQUIRE_FALSE(cfg.has_value());
    CHECK_THAT(cfg.error(), Catch::Contains(says));
  }
}

TEST_CASE("fault silence_axis: one axis of a unit, by name or index, switched on and off", "[three_axis]") {
  const std::vector<std::string> serials = {"SIM-0001", "SIM-0002"};
  FaultState state;
  state.units.resize(2);
  auto apply = [&](const json& j) {
    auto c = parse_fault_command(j, serials);
    INFO(j.dump());
    REQUIRE(c.has_value());
    apply_fault(state, *c, 10.0);
  };
  apply({{"name", "silence_axis"}, {"unit", 0}, {"axis", "z"}});
  CHECK(state.units[0].silent_axis == std::array<bool, 3>{false, false, true});
  CHECK(state.units[1].silent_axis == std::array<bool, 3>{false, false, false});
  apply({{"name", "silence_axis"}, {"unit", "SIM-0002"}, {"axis", 1}});  // an index: y
  CHECK(state.units[1].silent_axis == std::array<bool, 3>{false, true, false});
  const auto active = active_faults(state, serials, 10.0);
  REQUIRE(active.size() == 2);
  CHECK(active[0] == json({{"name", "silence_axis"}, {"axis", "z"}, {"unit", 0}, {"serial", "SIM-0001"}}));
  CHECK(active[1]["axis"] == "y");
  // Off without an axis: every axis of the unit speaks again.
  apply({{"name", "silence_axis"}, {"unit", 1}, {"on", false}});
  CHECK(state.units[1].silent_axis == std::array<bool, 3>{false, false, false});
  CHECK(state.units[0].silent_axis[2]);

  // The command-line form: the axis is the main parameter.
  auto j = fault_json_from_cli("silence_axis=z,unit=0");
  REQUIRE(j.has_value());
  CHECK(*j == json({{"cmd", "fault"}, {"name", "silence_axis"}, {"on", true}, {"axis", "z"}, {"unit", 0}}));

  CHECK(parse_fault_command({{"name", "silence_axis"}, {"unit", 0}}, serials).error() == "silence_axis: axis: missing");
  CHECK(parse_fault_command({{"name", "silence_axis"}, {"axis", "w"}}, serials).error() ==
        "silence_axis: axis: expected x, y, z or 0..2 (got \"w\")");
  CHECK(parse_fault_command({{"name", "silence_axis"}, {"axis", 3}}, serials).error() ==
        "silence_axis: axis: expected x, y, z or 0..2 (got 3)");
  CHECK(parse_fault_command({{"name", "silence_axis"}, {"axis", "x"}, {"fraction", 1}}, serials).error() ==
        "silence_axis.fraction: unknown field (known: axis, on, unit)");
}

TEST_CASE("the served rate unit's int32 counts carry the served table's largest rate, and clip only beyond it") {
  auto u = default_unit_layout(0, 100);
  REQUIRE(u.has_value());
  REQUIRE(u->gyro.mode == drivers::GyroMode::rate);
  CHECK(u->gyro.scale_dph_per_count == default_rate_scale_dph_per_count);
  // What the example configuration tells the daemon is what the mock encodes with.
  CHECK(example().units[0].gyro.scale_dph_per_count == u->gyro.scale_dph_per_count);
  constexpr double hi = std::numeric_limits<std::int32_t>::max();
  // The int32 counts hold +-hi x scale deg/h: at 1e-3 deg/h per count 596.5 deg/s.
  const double holds_dps = hi * u->gyro.scale_dph_per_count / 3600.0;
  CHECK(holds_dps == Approx(596.52).margin(0.01));
  CHECK(holds_dps > served_table_max_rate_dps);

  // A noiseless stream at the table's largest rate (+ and -): every frame's counts below the
  // limit, and the daemon's accumulator reads the rate back (the quantisation's error over a
  // second is at most one count, 1e-3 deg/h, in 100 frames).
  StreamParams p;
  p.frame_rate_hz = 100;
  p.counts_per_dph = u->counts_per_dph();
  p.sigma_a_dph = 0;
  p.startup_flag_s = 0;
  for (double dps : {served_table_max_rate_dps, -served_table_max_rate_dps, 1.2 * holds_dps}) {
    INFO(dps << " deg/s");
    GyroStream g(p);
    std::mt19937_64 rng(1);
    std::vector<StreamFrame> frames;
    g.second(0, dps * 3600.0, PowerWindow{}, rng, frames);
    drivers::SampleAccumulator acc(u->gyro);
    std::uint8_t seq = 0;
    for (const auto& f : frames) acc.add(drivers::can::encode({u->gyro.node_id, f.counts, seq++, drivers::can::status::valid}));
    const auto s = acc.close();
    REQUIRE(s.rate_dph.has_value());
    if (std::abs(dps) < holds_dps) {
      CHECK(s.frames_saturated == 0);
      CHECK(*s.rate_dph == Approx(dps * 3600.0).margin(1e-3));
    } else {
      // Beyond: every frame at the limit, the rate clipped to what the counts hold, and the
      // accumulator says so (the daemon flags the second out_of_range).
      CHECK(s.frames_saturated == frames.size());
      CHECK(*s.rate_dph == Approx(holds_dps * 3600.0).epsilon(1e-9));
    }
  }
}

TEST_CASE("mock bench options --axis-thermistors: coils per axis deeper in the housing, six channels a unit, x's own drift", "[three_axis][axis_thermistors]") {
  fogbench::mock::Options o;
  o.axes = 3;
  o.units = 3;
  o.coil = "lumped";
  o.axis_thermistors = true;
  o.axis_effects = {"x=0.3*T1y@20", "z=0.1*T1"};
  auto cfg = fogbench::mock::make_bench_config(o);
  INFO((cfg ? std::string() : cfg.error()));
  REQUIRE(cfg.has_value());
  for (const auto& u : cfg->sim.units) {
    REQUIRE(u.axis_coils.has_value());
    // y's and z's paths from the air 1.6 and 2.4 times x's (fogctl simulate's housing).
    CHECK((*u.axis_coils)[0].wall_tau_s == Approx(1.6 * u.coil.wall_tau_s));
    CHECK((*u.axis_coils)[1].wall_tau_s == Approx(2.4 * u.coil.wall_tau_s));
    CHECK(u.x_effects == "0.3*T1y@20");
    CHECK(u.axis_effects[1] == "0.1*T1");
  }
  // The served drivers configuration names the six channels per unit, on registers of their own
  // (the drivers' parser refuses overlaps), in both encodings.
  auto served = fogbench::mock::load_served_map("");
  REQUIRE(served);
  const json dj = fogbench::mock::drivers_config(fogbench::mock::Endpoints{}, *served, cfg->units);
  auto parsed = fogbench::drivers::parse_drivers_config(dj, FOGBENCH_SOURCE_DIR "/drivers/maps");
  INFO((parsed ? std::string() : parsed.error().to_string()));
  REQUIRE(parsed);
  REQUIRE(parsed->units.size() == 3);
  for (const auto& u : parsed->units) CHECK(u.has_axis_thermistors());
  CHECK(parsed->units[0].axis_thermistors[0][0].reg.address == 200);
  CHECK(parsed->units[0].axis_thermistors[1][1].reg.address == 265);
  CHECK(parsed->units[1].axis_thermistors[0][0].kind == fogbench::drivers::ThermistorKind::ntc);
  CHECK(parsed->units[1].axis_thermistors[1][0].reg.address == 500);
  CHECK(parsed->units[2].axis_thermistors[0][1].reg.address == 203);
  // The words the module serves for a temperature convert back on the axis's channel.
  auto words = encode_thermistor(cfg->units[1].axis_thermistors[1][1], 31.5);
  REQUIRE(words);
  auto back = fogbench::drivers::convert_thermistor(cfg->units[1].axis_thermistors[1][1],
                                                    std::span<const std::uint16_t>(words->data(), 2), "z T2");
  REQUIRE(back);
  CHECK(*back == Approx(31.5).margin(1e-3));

  // Refused: the flag without three axes; x's own drift, or a term of another axis's coil, without it.
  o.axes = 1;
  o.axis_effects.clear();
  cfg = fogbench::mock::make_bench_config(o);
  REQUIRE_FALSE(cfg.has_value());
  CHECK(cfg.error() == "--axis-thermistors needs --axes 3 (a one-axis unit has one coil)");
  o.axes = 3;
  o.axis_thermistors = false;
  o.axis_effects = {"x=0.3*T1y"};
  cfg = fogbench::mock::make_bench_config(o);
  REQUIRE_FALSE(cfg.has_value());
  CHECK_THAT(cfg.error(), Catch::Contains("own coil thermistor"));
}
