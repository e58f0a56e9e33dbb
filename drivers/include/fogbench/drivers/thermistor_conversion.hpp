// Coil thermistor channels: where a sensor's reading is, how it becomes a temperature (a scaled
// temperature register, or an NTC resistance through Steinhart-Hart), and when it is no reading
// at all (open circuit, short, out of range). Pure, shared with the mock bench.
#pragma once

#include <nlohmann/json_fwd.hpp>

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>

#include "fogbench/drivers/error.hpp"
#include "fogbench/drivers/register_map.hpp"

namespace fogbench::drivers {

// 1/T = a + b ln(R) + c ln(R)^3, T in kelvin, R in ohm.
struct SteinhartHart {
  double a = 0;
  double b = 0;
  double c = 0;

  double temp_c(double resistance_ohm) const noexcept;
};

enum class ThermistorKind {
  temperature,  // the module reports a temperature: temp_c = raw * scale + offset
  ntc,          // the module reports a resistance: resistance_ohm = raw * scale + offset
};

struct ThermistorChannelConfig {
  RegisterSpec reg;  // holding or input register of the module
  ThermistorKind kind = ThermistorKind::temperature;
  SteinhartHart coefficients;  // ntc only
  double min_c = -60.0;        // a plausible coil temperature; outside is out_of_range
  double max_c = 150.0;
  double min_ohm = 10.0;       // ntc: below this the sensor or its wiring is shorted
  double max_ohm = 1.0e6;      // ntc: at or above this the sensor is open (disconnected)
  // A raw value the module sends for a broken sensor (e.g. 32767 on many input modules).
  std::optional<double> open_circuit_raw;
};

// The temperature of one sensor from its register words, or an error naming `who` ("unit
// FOG-0002 T2"): open_circuit, out_of_range (short or implausible), corrupt (not a number).
Result<double> convert_thermistor(const ThermistorChannelConfig& channel,
                                  std::span<const std::uint16_t> words, std::string_view who);

// {"function": "input", "address": 3, "type": "float32", "kind": "ntc",
//  "steinhart_hart": {"a": ..., "b": ..., "c": ...}, "valid_c": {"min": -60, "max": 150},
//  "valid_ohm": {"min": 10, "max": 1e6}, "open_circuit_raw": 32767}
Result<ThermistorChannelConfig> parse_thermistor_channel(const nlohmann::json& value,
                                                         const std::string& path);

}  // namespace fogbench::drivers
