// Faults the mock bench injects on request, as the hardware would show them to the daemon:
// their names, the JSON command that switches one on or off (control socket), the command-line
// form (--fault NAME[=VALUE][,KEY=VALUE...]) that becomes the same JSON, and the state the
// server and the clock read. Pure: applying a fault here changes state, the bench acts on it.
#pragma once

#include <nlohmann/json.hpp>

#include <array>
#include <cstdint>
#include <limits>
#include <expected>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace fogbench::mock {

enum class FaultKind {
  refuse_modbus,    // close the listening socket: connects are refused
  drop_modbus,      // action: close the connected Modbus clients now
  stall_modbus,     // delay every reply by `ms`
  freeze_pv,        // the chamber's process value stops updating
  alarm,            // the chamber's alarm is raised
  lose_frames,      // lose a `fraction` of a unit's CAN frames (their sequence numbers skipped)
  lose_burst,       // action: lose the next `count` frames of a unit
  corrupt_frames,   // flip one bit in a `fraction` of a unit's frames: the CRC fails
  open_thermistor,  // a unit's sensor reads as an open circuit
  gyro_spike,       // add `dph` to a unit's gyro for `duration_s` simulated seconds
  power_off,        // a unit has no power (no frames); for `duration_s` if given, else until off
  power_cycle,      // action: a unit loses power for `off_s` simulated seconds, then restarts
  refuse_setpoint,  // the chamber controller refuses every setpoint written (exception, NA:, -6)
  // The serial gyro's line (--serial-gyro; serial_gyro.hpp), every 1/fraction-th serial frame:
  serial_garbage,   // `bytes` (default 5) bytes of garbage before it
  serial_cut,       // the frame cut in half (its first half only, then the next frame)
  serial_bad_crc,   // one bit of its CRC flipped
  serial_baud,      // the gyro sends at `baud` while the line reads at `line_baud` (default 921600)
  table_fault,      // the rate table's controller reports a fault (`text`), latched until reset
  drop_table,       // action: close the rate table's connected clients now
  silence_axis,     // one `axis` (x, y, z) of a three-axis unit sends no frame until switched off
};

inline constexpr std::array<FaultKind, 20> all_fault_kinds = {
    FaultKind::refuse_modbus, FaultKind::drop_modbus, FaultKind::stall_modbus,
    FaultKind::freeze_pv,     FaultKind::alarm,       FaultKind::lose_frames,
    FaultKind::lose_burst,    FaultKind::corrupt_frames, FaultKind::open_thermistor,
    FaultKind::gyro_spike,    FaultKind::power_off,   FaultKind::power_cycle,
    FaultKind::refuse_setpoint, FaultKind::serial_garbage, FaultKind::serial_cut,
    FaultKind::serial_bad_crc, FaultKind::serial_baud, FaultKind::table_fault, FaultKind::drop_table,
    FaultKind::silence_axis};

// The line baud rate serial_baud assumes when not given (the KVH 1775's default), bits/s.
inline constexpr int default_serial_line_baud = 921600;

// A power cycle without `off_s` keeps the unit off this long, simulated s.
inline constexpr double default_power_cycle_off_s = 3.0;

std::string_view to_string(FaultKind kind) noexcept;
std::optional<FaultKind> parse_fault_kind(std::string_view name) noexcept;

// The two Modbus devices; each has its listening socket unless they share one (gateway).
enum class Device : std::size_t { chamber = 0, thermistors = 1 };
std::string_view to_string(Device device) noexcept;

struct FaultCommand {
  FaultKind kind = FaultKind::freeze_pv;
  bool on = true;
  std::optional<Device> device;     // Modbus faults; empty: both devices
  std::optional<std::size_t> unit;  // unit faults, resolved to an index; empty: every unit
  std::optional<int> sensor;        // open_thermistor: 1 (T1) or 2 (T2); empty: both
  std::optional<std::size_t> axis;  // silence_axis: 0, 1, 2 (x, y, z); empty (off only): every axis
  double value = 0;                 // ms, fraction, count, dph or off_s, by kind; power_off:
                                    // duration_s (infinity when not given)
  double duration_s = 10.0;         // gyro_spike, simulated seconds
  int bytes = 5;                    // serial_garbage: bytes per run
  int line_baud = default_serial_line_baud;  // serial_baud: the rate the line reads at, bits/s
  std::string text;                 // table_fault: the controller's fault text ("" for its default)
};

// Parses {"cmd":"fault","name":"stall_modbus","on":true,"ms":800,"device":"chamber"}: the
// fields a fault takes are named in docs/mock-bench.md; any other field is refused by name.
// "unit" is a 0-based index or a serial from `serials`.
std::expected<FaultCommand, std::string> parse_fault_command(const nlohmann::json& command,
                                                             const std::vector<std::string>& serials);

// "stall_modbus=800,device=chamber" -> {"cmd":"fault","name":"stall_modbus","on":true,
// "ms":800,"device":"chamber"}: VALUE is the fault's main parameter, KEY=VALUE any other field;
// numbers become JSON numbers, anything else a string.
std::expected<nlohmann::json, std::string> fault_json_from_cli(std::string_view text);

struct UnitFaults {
  double lose_fraction = 0;
  std::uint32_t lose_burst = 0;  // frames still to lose
  double corrupt_fraction = 0;
  bool open_t1 = false;
  bool open_t2 = false;
  double spike_dph = 0;
  double spike_until_s = 0;  // the spike applies to the seconds starting before this time
  // No power from power_off_from_s (inclusive) to power_on_at_s (exclusive), simulated s.
  double power_off_from_s = std::numeric_limits<double>::infinity();
  double power_on_at_s = 0;
  // By axis (x, y, z): the axis sends no frame (silence_axis). Its stream runs on unseen, so
  // when it speaks again its counter has moved on: the reader counts the silence as lost.
  std::array<bool, 3> silent_axis{};
};

// The serial gyro's line faults (the first unit's frames on --serial-gyro's pty).
struct SerialLineFaults {
  double garbage_fraction = 0;  // of the frames with garbage before them
  int garbage_bytes = 5;
  double cut_fraction = 0;      // of the frames cut in half
  double bad_crc_fraction = 0;  // of the frames with a CRC bit flipped
  int baud = 0;                 // the gyro's sending rate, bits/s; 0: the line's own
  int line_baud = default_serial_line_baud;
  friend bool operator==(const SerialLineFaults&, const SerialLineFaults&) = default;
};

struct FaultState {
  std::array<bool, 2> refuse{};    // by Device
  std::array<int, 2> stall_ms{};   // by Device
  bool freeze_pv = false;
  bool alarm = false;
  bool refuse_setpoint = false;
  bool table_fault = false;        // the rate table's fault condition
  std::string table_fault_text;
  std::uint64_t table_drops = 0;   // drop_table actions so far (the table's server closes its
                                   // clients when this moves)
  std::vector<UnitFaults> units;
  SerialLineFaults serial;
};

// Switches a fault on or off. `next_second_s` is the start of the next simulated second (where
// a spike begins, and where the power goes off or comes back). drop_modbus changes no state: the caller closes the clients.
void apply_fault(FaultState& state, const FaultCommand& command, double next_second_s);

// The faults in force, each as the JSON command that would set it (plus "serial" for units
// and "until_s" for a spike, "count" left for a burst), for the status reply.
nlohmann::json active_faults(const FaultState& state, const std::vector<std::string>& serials,
                             double next_second_s);

}  // namespace fogbench::mock
