// The rate-table controller's command set as both ends know it: Acutronic ACUTROL (ACS2000 /
// ACUTROL3000) remote commands in their SCPI-like long form (":mode:rate 1", ":demand:rate 1,
// 100.0", ":read:position 1"), one line each way, CR LF, over TCP. Command texts, reply parsing
// and the status word, with no I/O, so the driver (drivers/src/acutrol_rate_table.cpp) and the
// mock bench's peer (sim/mock/rate_table.cpp) share one definition. Which commands come from a
// published source and which are this project's assumption: docs/drivers.md, "Rate table".
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace fogbench::drivers::acutrol {

// Every command and reply is one line ending in CR LF.
inline constexpr std::string_view line_end = "\r\n";
// The port of the public ACUTROL client this dialect follows (docs/drivers.md); not confirmed
// from a vendor document: configurations should name their port.
inline constexpr std::uint16_t default_tcp_port = 9888;

// A setting accepted.
inline constexpr std::string_view ok_reply = "OK";
// A command refused: "ERR <code>: <text>" (assumed form, docs/drivers.md).
inline constexpr std::string_view error_prefix = "ERR";

// Refusal codes the mock answers and the driver names (assumed numbering, docs/drivers.md).
inline constexpr int err_syntax = 1;          // not a command, or its arguments do not parse
inline constexpr int err_rate_limit = 2;      // a rate demand beyond the table's rate limit
inline constexpr int err_accel_limit = 3;     // an acceleration demand beyond the table's limit
inline constexpr int err_fault_active = 4;    // a motion command while a fault holds the table
inline constexpr int err_interlock_open = 5;  // a motion command with the interlock open
inline constexpr int err_wrong_mode = 6;      // a demand that does not fit the current mode
std::string_view describe_error(int code) noexcept;

// The commands, for axis `axis` (1 on a single-axis table). Numbers with 6 decimals.
std::string mode_rate(int axis);          // ":mode:rate 1": rate mode (the table spins at a demand)
std::string mode_position(int axis);      // ":mode:position 1"
std::string mode_off(int axis);           // ":mode:off 1"
std::string demand_rate(int axis, double rate_dps);              // ":demand:rate 1, 100.000000"
std::string demand_position(int axis, double position_deg);      // ":demand:position 1, 90.000000"
std::string demand_acceleration(int axis, double accel_dps2);    // ":demand:acceleration 1, 50.0"
std::string read_rate(int axis);          // ":read:rate 1" -> "100.001234" deg/s
std::string read_position(int axis);      // ":read:position 1" -> "123.456789" deg, 0..360
std::string read_status(int axis);        // ":read:status 1" -> the status word, decimal
std::string read_fault(int axis);         // ":read:fault 1" -> the fault text, "NONE" if none
std::string interlock_close(int axis);    // ":interlock:close 1": motor power on
std::string interlock_open(int axis);     // ":interlock:open 1": motor power off
std::string interlock_reset(int axis);    // ":interlock:reset 1": clear a fault that has gone

// The status word (":read:status"): assumed layout, docs/drivers.md.
inline constexpr unsigned status_interlock_closed = 1u << 0;
inline constexpr unsigned status_moving = 1u << 1;       // |rate| above the standstill threshold
inline constexpr unsigned status_at_rate = 1u << 2;      // rate mode, the demand reached
inline constexpr unsigned status_in_position = 1u << 3;  // position mode, the demand reached
inline constexpr unsigned status_fault = 1u << 4;        // a fault holds the table
inline constexpr unsigned status_mode_rate = 1u << 5;
inline constexpr unsigned status_mode_position = 1u << 6;
inline constexpr std::string_view no_fault = "NONE";

// A number reply ("100.001234", "-5", "1.5E+02"): finite, nothing after it.
std::optional<double> parse_number(std::string_view reply);
// A status word reply: a decimal 0..65535.
std::optional<unsigned> parse_status(std::string_view reply);
// "ERR 2: RATE LIMIT EXCEEDED" -> {2, "RATE LIMIT EXCEEDED"}; empty when not an error reply.
struct ErrorReply {
  int code = 0;
  std::string text;
};
std::optional<ErrorReply> parse_error(std::string_view reply);
std::string format_error(int code, std::string_view text);  // "ERR 2: RATE LIMIT EXCEEDED"
// A number as the controller shows it: 6 decimals ("100.000000").
std::string format_number6(double value);

// A command line as the controller reads it: its header nodes (each may be abbreviated to any
// prefix, any case: ":D:R" is ":demand:rate"), the axis and an optional value.
enum class Verb { mode, demand, read, interlock };
enum class Item { rate, position, acceleration, off, status, fault, open, close, reset };
struct Command {
  Verb verb = Verb::read;
  Item item = Item::rate;
  int axis = 0;
  std::optional<double> value;  // demand's value
};
// Empty when the line is not a command of this set; `why` says what is wrong.
std::optional<Command> parse_command(std::string_view line, std::string* why = nullptr);

}  // namespace fogbench::drivers::acutrol
