// fogbenchd's command protocol as both ends know it (docs/protocol.md): its version, its limits,
// its error codes with their wire strings, and the shapes of the messages both ends read or
// write (hello, a stored sample, a pushed sample, an event) with their JSON forms. The daemon
// writes them, fogctl reads them; neither re-types a string or a field name of the other.
// framing.hpp holds the reading side (lines, nesting and duplicate keys).
#pragma once

#include <cstddef>
#include <cstdint>
#include <expected>
#include <optional>
#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

namespace fogbench::protocol {

// The protocol's version, sent in `hello`: it grows by adding fields and message types; a change
// that cannot be made that way increments it. A client refuses a daemon of another version.
inline constexpr int kProtocolVersion = 1;

// A request line may be at most this long, newline excluded (hello's limits.max_line_bytes).
inline constexpr std::size_t kMaxLineBytes = 1024 * 1024;
// A request may nest arrays and objects at most this deep; the request object itself is level
// 1 (hello's limits.max_depth). nlohmann::json copies, dumps and destroys a value recursively,
// so a deeper one (100,000 '[' fit in a line) would overflow the stack: it is refused while it
// is parsed, before any of it is built.
inline constexpr std::size_t kMaxDepth = 64;
// A line from the daemon (a reply, a pushed message) is at most this long: the largest reply is
// a page of run.samples (10,000 rows of about 300 bytes) or a run.get, far below it. A client
// reads no more than this for one line, so a daemon gone wrong cannot make it grow without end.
inline constexpr std::size_t kMaxMessageBytes = 64 * 1024 * 1024;

// The `code` of an error reply: stable strings, documented in docs/protocol.md.
enum class ErrorCode {
  bad_json,         // the line is not JSON
  bad_request,      // JSON, but not a request: missing or mistyped field
  unknown_command,  // no such cmd
  not_found,        // no such run, unit, model, profile
  busy,             // a run is active
  invalid_profile,  // the profile does not parse
  limits,           // the profile leaves the chamber's limits
  unknown_serial,   // a serial not configured on this bench, or without a model to verify
  forbidden,        // a command that changes something, on a connection that may only read (TCP)
  internal,         // storage or analysis failed; the daemon keeps running
  unavailable,      // the bench cannot run now: the chamber link is down (run.start, run.resume)
  invalid_config,   // config.reload: the configuration file does not parse; nothing changed
};
std::string_view to_string(ErrorCode c);
// The code of a wire string; nullopt for one this side does not know (a newer daemon's).
std::optional<ErrorCode> error_code_from_string(std::string_view s);

// The first message on every connection.
struct Hello {
  std::string version;  // the daemon's release, e.g. "0.1.0"
  int protocol = kProtocolVersion;
  std::size_t max_line_bytes = kMaxLineBytes;
  std::size_t max_depth = kMaxDepth;
};
nlohmann::json to_json(const Hello& h);
// A hello as received: refused (with a message for people) when it is not a hello, has no
// protocol version, or speaks another version than kProtocolVersion.
std::expected<Hello, std::string> hello_from_json(const nlohmann::json& j);

// A JSON number, or null for a value not read (JSON has no NaN): nullopt and non-finite are null.
nlohmann::json number_or_null(std::optional<double> v);

// One stored second of one unit, as run.samples pages it. Every reading may be absent (null on
// the wire); `phase` is model/run.hpp's phase name ("settle", "hold", "heating", "cooling").
struct Sample {
  double t_s = 0.0;  // run clock, s since the run's start
  std::optional<double> wall_time;  // unix time, s
  std::optional<double> setpoint_c, chamber_c, gyro_dph;
  std::optional<std::int64_t> frames;  // gyro frames averaged
  std::optional<double> t1_c, t2_c;
  std::string phase = "unknown";
  std::optional<int> step;
  std::uint8_t flags = 0;  // quality bits of model/run.hpp
  std::optional<double> since_power_on_s;
  // The daemon's live compensated rate, deg/h: null when it computed none (docs/daemon.md).
  std::optional<double> compensated_dph;
  // The rate the daemon commanded the rate table to, deg/s: null when the run drove no table.
  std::optional<double> rate_in_dps;
  // A three-axis unit's axes 1 and 2 (y, z), deg/h (gyro_dph is axis 0, x). On the wire only for
  // a three-axis unit (three_axis; read back from the presence of gyro_y_dph), each a number or
  // null where the axis sent nothing usable that second; a one-axis unit's have no such fields.
  bool three_axis = false;
  std::optional<double> gyro_y_dph, gyro_z_dph;
  // A three-axis unit whose axes have their own coil thermistors: y's and z's centre and outer
  // wall, degC (t1_c, t2_c are x's). On the wire only for such a unit (axis_thermistors; read
  // back from the presence of t1_y_c), each a number or null where the sensor was not read.
  bool axis_thermistors = false;
  std::optional<double> t1_y_c, t2_y_c, t1_z_c, t2_z_c;
};
nlohmann::json to_json(const Sample& s);
// A row of run.samples as received; the error names the field.
std::expected<Sample, std::string> sample_from_json(const nlohmann::json& j);

// The `sample` message pushed to subscribers: one unit's second while a run is active.
struct SampleMessage {
  std::int64_t run_id = 0;
  double t_s = 0.0;
  std::string state;  // the run's state
  std::string phase;  // the profile's phase (profiles' names)
  std::size_t step = 0;
  double elapsed_s = 0.0, remaining_s = 0.0;
  double setpoint_c = 0.0;
  std::optional<double> chamber_c;
  int unit = 0;
  std::string serial;
  std::optional<double> gyro_dph;
  std::int64_t frames = 0;
  std::optional<double> t1_c, t2_c;
  std::uint8_t flags = 0;
  std::optional<double> since_power_on_s;
  // gyro_dph minus the unit's model's drift, computed live as the firmware would, deg/h; null
  // without a model, while the compensator warms up, or when an input is missing.
  std::optional<double> compensated_dph;
  // The rate table's commanded rate this second, deg/s: only for a run that drives a table (the
  // message of any other run has no such field, as before).
  std::optional<double> rate_in_dps;
  // A three-axis unit's axes 1 and 2 (y, z), deg/h (gyro_dph is axis 0, x). On the wire only for
  // a three-axis unit (three_axis; read back from the presence of gyro_y_dph), each a number or
  // null where the axis sent nothing usable that second; a one-axis unit's have no such fields.
  bool three_axis = false;
  std::optional<double> gyro_y_dph, gyro_z_dph;
  // A three-axis unit whose axes have their own coil thermistors: y's and z's centre and outer
  // wall, degC (t1_c, t2_c are x's). On the wire only for such a unit (axis_thermistors; read
  // back from the presence of t1_y_c), each a number or null where the sensor was not read.
  bool axis_thermistors = false;
  std::optional<double> t1_y_c, t2_y_c, t1_z_c, t2_z_c;
};
nlohmann::json to_json(const SampleMessage& s);
std::expected<SampleMessage, std::string> sample_message_from_json(const nlohmann::json& j);

// The `event` message pushed to subscribers (and stored as the run's audit trail): `kind` is one
// of state, phase, command, alarm, fault, note; `detail` its object.
struct EventMessage {
  std::int64_t run_id = 0;
  std::optional<double> t_s;
  std::string kind;
  nlohmann::json detail = nlohmann::json::object();
};
nlohmann::json to_json(const EventMessage& e);
std::expected<EventMessage, std::string> event_message_from_json(const nlohmann::json& j);

}  // namespace fogbench::protocol
