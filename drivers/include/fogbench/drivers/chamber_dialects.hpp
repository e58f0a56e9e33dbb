// The ASCII chamber controllers' dialects as both ends know them: Espec P300/SCP-220 and
// Weiss/Voetsch SIMSERV. Command texts, reply parsing and the error tables, with no I/O, so the
// drivers (drivers/src/espec_chamber.cpp, simserv_chamber.cpp) and the mock bench's peers
// (sim/mock/ascii_chamber.cpp) share one definition. Sources of each command: docs/drivers.md,
// "ASCII chamber controllers".
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace fogbench::drivers {

// A line as it can be shown in a message: printable ASCII kept, anything else as <XX> (hex), so
// SIMSERV's 0xB6 separators and a stray CR show as <B6> and <0D>.
std::string printable(std::string_view line);

namespace espec {

// Every command and reply is one line ending in CR LF.
inline constexpr std::string_view line_end = "\r\n";
// The TCP port of the controllers' LAN option as the issue gives it; not confirmed from a
// vendor document (docs/drivers.md): configurations should name their port.
inline constexpr std::uint16_t default_tcp_port = 57732;

inline constexpr std::string_view cmd_type = "TYPE?";    // "T,S2,160.0": sensor, controller, max degC
inline constexpr std::string_view cmd_temp = "TEMP?";    // "23.5,20.0,100.0,-40.0": pv, sp, upper, lower
inline constexpr std::string_view cmd_mon = "MON?";      // "23.5,,CONSTANT,0": temp, humidity, mode, alarms
inline constexpr std::string_view cmd_mode = "MODE?";    // "CONSTANT", "STANDBY", "OFF", "RUN ..."
inline constexpr std::string_view cmd_alarm = "ALARM?";  // "0" or "2,3,5": count, then the codes
inline constexpr std::string_view ok_prefix = "OK:";     // a setting accepted: "OK:TEMP,S20.0"
inline constexpr std::string_view error_prefix = "NA:";  // refused: "NA:DATA OUT OF RANGE"

// "TEMP, S20.0" (0.1 degC resolution, as the controller keeps it).
std::string set_temp_command(double setpoint_c);
// "MODE, CONSTANT" (run at the constant setpoint) or "MODE, STANDBY" (controller on, no control).
std::string mode_command(bool run);

struct TempReply {
  double process_value_c = 0;
  double setpoint_c = 0;
  double upper_alarm_c = 0;
  double lower_alarm_c = 0;
};
std::optional<TempReply> parse_temp(std::string_view reply);

struct MonReply {
  double temp_c = 0;
  std::optional<double> humidity_pct;  // empty field on temperature-only chambers
  std::string mode;
  int alarms = 0;  // number of active alarms
};
std::optional<MonReply> parse_mon(std::string_view reply);

// The alarm codes active (empty: none).
std::optional<std::vector<int>> parse_alarm(std::string_view reply);

// A MODE? answer: OFF, STANDBY, CONSTANT or RUN (program; "RUN 1", "RUN PAUSE"...). Empty when
// the text is none of them.
enum class Mode { off, standby, constant, run };
std::optional<Mode> parse_mode(std::string_view reply);
std::string_view to_string(Mode mode) noexcept;

// What an NA: code means, from the controller's error list ("CMD ERR": "unrecognized command");
// "no description" for a code outside it.
std::string_view describe_error(std::string_view code) noexcept;

}  // namespace espec

namespace simserv {

// A command is its 5-digit number, the chamber index and its arguments, separated by 0xB6 and
// ended by CR; a reply is a return code and its values, the same way.
inline constexpr char separator = '\xB6';
inline constexpr char terminator = '\r';
inline constexpr std::uint16_t default_tcp_port = 2049;

inline constexpr int cmd_set_setpoint = 11001;  // args: variable (1 = temperature), value degC
inline constexpr int cmd_get_setpoint = 11002;  // args: variable
inline constexpr int cmd_get_value = 11004;     // args: variable; the actual value
inline constexpr int cmd_start_manual = 14001;  // args: 1, then 1 (start) or 0 (stop)
inline constexpr int cmd_get_status = 10012;    // no args; a bit field, below
inline constexpr int cmd_get_info = 99997;      // no args; the chamber's type text
inline constexpr int temperature_variable = 1;

// Return codes.
inline constexpr int ok = 1;
inline constexpr int err_unknown_command = -5;
inline constexpr int err_bad_parameters = -6;
inline constexpr int err_not_readable = -8;
std::string_view describe_code(int code) noexcept;

// Status (10012): 1 test not running, 3 running, +4 warnings present, +8 alarms present.
inline constexpr unsigned status_running_bit = 2;
inline constexpr unsigned status_warning_bit = 4;
inline constexpr unsigned status_alarm_bit = 8;

// "11001<B6>1<B6>1<B6>20.0<CR>" for (11001, 1, {"1", "20.0"}).
std::string format_command(int number, int chamber_index, std::span<const std::string> args);
// The reply's line (terminator stripped) into its fields, or empty for a line that is not one
// (no numeric first field).
struct Reply {
  int code = 0;
  std::vector<std::string> values;
};
std::optional<Reply> parse_reply(std::string_view line);
// A command line (terminator stripped) as the controller reads it: number, chamber index, args.
struct Command {
  int number = 0;
  int chamber_index = 0;
  std::vector<std::string> args;
};
std::optional<Command> parse_command(std::string_view line);
// "1<B6>23.5<CR><LF>" for (1, {"23.5"}): the controllers end a reply with CR LF.
std::string format_reply(int code, std::span<const std::string> values);
std::string format_value(double value_c);  // "20.0": one decimal, as the controller shows it

}  // namespace simserv

}  // namespace fogbench::drivers
