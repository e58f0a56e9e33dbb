// What the mock bench serves and where: each unit's gyro encoding (CAN node id, rate or
// increment counts) and coil thermistor channels, the chamber's register map, and the
// daemon-side drivers configuration that reads exactly that. Pure: no sockets, no threads.
//
// The default layout continues drivers/examples/mock-bench.json: unit 0 there is an even unit
// here, unit 1 an odd one, and every further unit repeats the pattern at the next registers.
#pragma once

#include <nlohmann/json.hpp>

#include <array>
#include <cstdint>
#include <expected>
#include <string>
#include <vector>

#include "fogbench/drivers/register_map.hpp"
#include "fogbench/drivers/sample_accumulator.hpp"
#include "fogbench/drivers/thermistor_conversion.hpp"

namespace fogbench::mock {

inline constexpr std::size_t max_units = 32;
inline constexpr int max_frame_rate_hz = 10000;

struct UnitLayout {
  std::string serial;
  // What the daemon is told about the gyro: node id, mode, scale and, in increment mode, the
  // nominal frame rate the daemon multiplies the mean increment by.
  drivers::GyroChannelConfig gyro;
  int frame_rate_hz = 100;  // frames actually sent per simulated second
  // Per axis (gyro.axes of them), the constant bias the axis adds to the unit's drift, deg/h:
  // axis 0's is 0 (it is the one-axis gyro), axes 1 and 2 of a three-axis unit have their own
  // (drawn from the seed by make_bench_config, served in the ready line).
  std::vector<double> axis_bias_dph = {0.0};
  nlohmann::json t1_json, t2_json;  // the channels as a drivers configuration spells them
  drivers::ThermistorChannelConfig t1, t2;
  // A three-axis unit with thermistors per axis: y's and z's channels ([0] y, [1] z, each
  // {T1, T2}), t1 and t2 being x's; empty when the axes share t1 and t2.
  std::vector<std::array<nlohmann::json, 2>> axis_json;
  std::vector<std::array<drivers::ThermistorChannelConfig, 2>> axis_thermistors;

  // Counts of one frame per deg/h of rate, by the drivers' own conversion (in increment mode
  // the increment of one nominal frame period: see docs/mock-bench.md).
  double counts_per_dph() const noexcept { return 1.0 / gyro.mean_counts_to_rate_dph(1.0); }
};

// The rate-mode units' scale, deg/h per count. Frames carry int32 counts, so the scale bounds
// the rate a frame can carry: 1e-3 deg/h per count holds +-2,147,483 deg/h (+-596.5 deg/s),
// beyond the daemon's rate table limit (max_rate_dps, 500 deg/s, the served rate_table_config's).
inline constexpr double default_rate_scale_dph_per_count = 1e-3;
// The |rate| the served rate_table_config lets the daemon command, deg/s: what the units' counts
// hold (the mock table itself would turn up to 1000 deg/s, RateTableSpec).
inline constexpr double served_table_max_rate_dps = 500.0;
static_assert(default_rate_scale_dph_per_count * 2147483647.0 > served_table_max_rate_dps * 3600.0,
              "the served rate units' int32 counts must hold the table's largest rate");

// Unit i (0-based), serial SIM-000(i+1). Even units: rate counts of 1e-3 deg/h, thermistors as
// int16 centi-degC at input i and i+1 (open circuit 32767). Odd units: increment counts of
// 1e-7 deg at a nominal 8000 frames/s, NTC resistances as float32 at input 100+2(i-1) and
// 102+2(i-1). Node id 257 + i; with `axes` 3, 257 + 4i (axis k on 257 + 4i + k: the units'
// ids never meet). With `axis_thermistors` (axes 3 only) y's and z's channels of the same type
// follow at 200 + i, 201 + i (y) and 264 + i, 265 + i (z) for even units, at 400+2(i-1),
// 402+2(i-1) (y) and 500+2(i-1), 502+2(i-1) (z) for odd ones.
std::expected<UnitLayout, std::string> default_unit_layout(std::size_t i, int frame_rate_hz, int axes = 1,
                                                           bool axis_thermistors = false);

// The built-in chamber map: drivers/maps/mock.json as it was when fogbench-sim was built.
const char* builtin_map_json() noexcept;

struct ServedMap {
  nlohmann::json json;   // as read: inlined into the drivers configuration
  drivers::RegisterMap map;
};
// Loads a map file, or the built-in mock map when `file` is empty.
std::expected<ServedMap, std::string> load_served_map(const std::string& file);

// Where the Modbus devices are, for the drivers configuration and the ready line.
struct Endpoints {
  std::string host = "127.0.0.1";
  int chamber_port = 1502;
  int chamber_unit = 1;
  int thermistor_port = 1503;  // the chamber's port in gateway mode
  int thermistor_unit = 2;
  std::string can_socket;
};

// A complete drivers configuration (docs/drivers.md) for what is served: parse_drivers_config
// accepts it as it is, the map inlined.
nlohmann::json drivers_config(const Endpoints& where, const ServedMap& map,
                              const std::vector<UnitLayout>& units);

// The resistance (ohm) of an NTC at temp_c: the inverse of the Steinhart-Hart equation
// 1/T = a + b ln R + c (ln R)^3, solved for ln R in closed form (Cardano).
double ntc_resistance_ohm(const drivers::SteinhartHart& sh, double temp_c) noexcept;

// The register words a module sends for a coil at temp_c on this channel (a temperature, or an
// NTC's resistance). Refuses a value the register cannot hold.
std::expected<std::array<std::uint16_t, 2>, std::string> encode_thermistor(
    const drivers::ThermistorChannelConfig& channel, double temp_c);
// The words of a disconnected sensor: the channel's open_circuit_raw, else for an NTC ten times
// the resistance at which the channel declares an open circuit.
std::array<std::uint16_t, 2> encode_open_circuit(const drivers::ThermistorChannelConfig& channel);

// The words of a raw (unscaled) value of a register, by its width and word order.
std::array<std::uint16_t, 2> raw_words(const drivers::RegisterSpec& spec, std::uint32_t raw) noexcept;

}  // namespace fogbench::mock
