// The mock bench's options (command line, optional per-unit JSON file) and their translation
// into a BenchConfig, with every refusal naming the option or field. Pure: reads only the
// files it is given.
#pragma once

#include <cstdint>
#include <expected>
#include <optional>
#include <string>
#include <vector>

#include "bench.hpp"

namespace fogbench::mock {

// The chamber and coils start at rest at --start-c; a wider range is no chamber's.
inline constexpr double min_start_c = -80.0, max_start_c = 180.0;

struct Options {
  std::string host = "127.0.0.1";
  int modbus_port = 1502;       // the chamber controller; 0: ephemeral
  int thermistor_port = 1503;   // the thermistor module; 0: ephemeral
  bool gateway = false;         // serve the module on the chamber's port instead
  int chamber_unit = 1;
  int thermistor_unit = 2;
  std::string can_socket = "/tmp/fogbench-mock-can.sock";
  std::string control;          // control socket path; empty: none
  std::optional<int> units;     // default: the config file's units, else 2
  double time_scale = 1.0;
  std::uint64_t seed = 1;
  std::vector<std::string> effects;  // added to every unit's drift
  std::string coil = "distributed";  // every unit's coil model (a --config unit's coil.model overrides it)
  double start_c = 20.0;
  std::string config_file;
  std::vector<std::string> faults;   // NAME[=VALUE][,KEY=VALUE...]
  int frame_rate_hz = 100;
  int axes = 1;                      // every unit's gyro axes: 1, or 3 (axis k on node id + k)
  double axis_bias_dph = 1.0;        // 1 sigma of the y and z axes' own biases (seeded), deg/h
  std::vector<std::string> axis_effects;  // with axes 3: "y=0.5*T1", an axis's own drift, every unit
  bool axis_thermistors = false;     // with axes 3: each axis a coil and thermistors of its own (y's, z's deeper in the housing)
  bool no_startup_flag = false;      // a gyro kind without the warm-up status bit: no frame carries `warming_up`
  double frame_noise_dph = 0;        // extra white noise per frame, on top of the gyro's own
  double warmup_dph = 0;             // every unit's warm-up after power-on: A*exp(-t/tau)
  double warmup_tau_s = 600;
  std::string map_file;              // empty: the built-in drivers/maps/mock.json
  double duration_s = 0;
  bool paced = false;                // the clock moves only on {"cmd":"advance"} (docs/mock-bench.md)
  std::string chamber_dialect = "modbus";  // modbus, espec or simserv (ascii_chamber.hpp)
  std::string serial_gyro;   // path of a link to a pty serving unit 1's frames serially; empty: none
  std::string serial_frame;  // the serial frame layout's JSON file (drivers/examples/kvh-1775-format-a.json)
  std::optional<int> rate_table_port;  // serve a rate table (ACUTROL command set) here; 0: ephemeral
};

// Joins effects in the term language with '+' (or '-' when one starts with a minus).
std::string join_effects(const std::vector<std::string>& effects);

std::expected<BenchConfig, std::string> make_bench_config(const Options& options);

}  // namespace fogbench::mock
