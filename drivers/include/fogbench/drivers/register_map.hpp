// Modbus register maps: the typed description of a register (table, address, type, scale, word
// order), a chamber controller's map loaded from JSON with validation, and the conversions
// between register words and engineering values. Pure: no libmodbus, so the mock bench serves
// exactly the map the drivers read.
#pragma once

#include <nlohmann/json_fwd.hpp>

#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "fogbench/drivers/error.hpp"

namespace fogbench::drivers {

// The four Modbus data tables. Coils and holding registers are writable.
enum class RegisterFunction { holding, input, coil, discrete };
enum class ValueType { boolean, int16, uint16, int32, uint32, float32 };
// For 32-bit types: which of the two consecutive registers holds the high 16 bits. Bytes inside a
// register are big-endian by the Modbus specification; only the word order varies by vendor.
enum class WordOrder { high_first, low_first };

std::string_view to_string(RegisterFunction function) noexcept;
std::string_view to_string(ValueType type) noexcept;
std::string_view to_string(WordOrder order) noexcept;
bool is_bit_table(RegisterFunction function) noexcept;
bool is_writable(RegisterFunction function) noexcept;

// One value in a device: engineering value = raw * scale + offset.
struct RegisterSpec {
  RegisterFunction function = RegisterFunction::holding;
  std::uint16_t address = 0;  // zero-based protocol address (register 40001 is holding 0)
  ValueType type = ValueType::uint16;
  WordOrder word_order = WordOrder::high_first;
  double scale = 1.0;
  double offset = 0.0;

  // Registers (or bits) the value occupies: 2 for 32-bit types, else 1.
  std::uint16_t width() const noexcept;
  // "holding 300 (int16)" or "input 2..3 (float32, high_first)", for messages.
  std::string describe() const;
};

// The raw register contents as an unsigned integer (32-bit types combined by word order).
// `words` holds width() words; for bit tables words[0] is 0 or 1.
std::uint32_t raw_unsigned(const RegisterSpec& spec, std::span<const std::uint16_t> words) noexcept;

// The raw value by type, before scale and offset (a float32 that is not finite is `corrupt`).
Result<double> decode_raw(const RegisterSpec& spec, std::span<const std::uint16_t> words);

// raw * scale + offset, with the raw value interpreted by type. A float32 that is not finite is
// `corrupt`: no device means NaN as a temperature.
Result<double> decode_value(const RegisterSpec& spec, std::span<const std::uint16_t> words);

// The inverse: the words to write for an engineering value. Integer types round to nearest. A
// value whose raw form does not fit the type is `out_of_range`, never wrapped or clamped.
Result<std::array<std::uint16_t, 2>> encode_value(const RegisterSpec& spec, double value);

// ---- a chamber controller's map ------------------------------------------------------------

struct RunSpec {  // run/stop: a coil, or a holding register written with on/off values
  RegisterSpec reg;
  std::uint16_t on_value = 1;
  std::uint16_t off_value = 0;
};

struct AlarmSpec {  // alarm active when (raw & mask) != 0
  RegisterSpec reg;
  std::uint32_t mask = 0xFFFFFFFFu;
};

struct StatusSpec {  // a status word; named bits are reported by name
  RegisterSpec reg;
  std::vector<std::pair<std::string, int>> bits;  // name, bit number
};

struct CheckedSpec {  // identity or units: read at bring-up, compared with `expect` if given
  RegisterSpec reg;
  std::optional<std::uint32_t> expect;
};

struct RegisterMap {
  std::string name;
  std::string source;           // the document the addresses come from
  RegisterSpec setpoint;        // written, degC after scale/offset
  RegisterSpec process_value;   // read, degC after scale/offset
  RunSpec run;
  AlarmSpec alarm;
  std::optional<StatusSpec> status;
  std::optional<CheckedSpec> identity;
  std::optional<CheckedSpec> units;
};

// Parses one register description. `path` prefixes the field names in errors; `extra_keys` are
// further fields the caller reads itself (e.g. "steinhart_hart" of a thermistor channel).
Result<RegisterSpec> parse_register_spec(const nlohmann::json& value, const std::string& path,
                                         std::span<const std::string_view> extra_keys = {});

// Parses and validates a chamber map (docs/chamber-maps.md). Refuses, naming the field path:
// unknown fields and types, a missing required register (setpoint, process_value, run, alarm),
// a written register in a read-only table, overlapping registers in one table.
Result<RegisterMap> parse_register_map(const nlohmann::json& value, const std::string& path = "");

// Reads a JSON file and parses it as a map; errors name the file.
Result<RegisterMap> load_register_map(const std::string& file_path);

}  // namespace fogbench::drivers
