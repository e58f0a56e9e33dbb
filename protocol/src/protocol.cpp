// The protocol's codes, hello and message shapes to and from JSON (protocol.hpp).
#include "fogbench/protocol/protocol.hpp"

#include <array>
#include <cmath>
#include <utility>

namespace fogbench::protocol {

using nlohmann::json;

namespace {

constexpr std::array<std::pair<ErrorCode, std::string_view>, 12> kCodes{{
    {ErrorCode::bad_json, "bad_json"},
    {ErrorCode::bad_request, "bad_request"},
    {ErrorCode::unknown_command, "unknown_command"},
    {ErrorCode::not_found, "not_found"},
    {ErrorCode::busy, "busy"},
    {ErrorCode::invalid_profile, "invalid_profile"},
    {ErrorCode::limits, "limits"},
    {ErrorCode::unknown_serial, "unknown_serial"},
    {ErrorCode::forbidden, "forbidden"},
    {ErrorCode::internal, "internal"},
    {ErrorCode::unavailable, "unavailable"},
    {ErrorCode::invalid_config, "invalid_config"},
}};

// Readers of a received object: each names the field that is missing or of the wrong type.
class Reader {
 public:
  Reader(const json& j, const char* what) : j_(j), what_(what) {}
  bool ok() const { return error_.empty(); }
  const std::string& error() const { return error_; }

  double number(const char* key) {
    if (!present(key) || !j_[key].is_number()) return fail(key, "expected a number"), 0.0;
    return j_[key].get<double>();
  }
  // null (a value not read) and an absent field are nullopt.
  std::optional<double> opt_number(const char* key) {
    if (!present(key) || j_[key].is_null()) return std::nullopt;
    if (!j_[key].is_number()) return fail(key, "expected a number or null"), std::nullopt;
    return j_[key].get<double>();
  }
  template <class Int>
  Int integer(const char* key, Int fallback) {
    if (!present(key) || j_[key].is_null()) return fallback;
    if (!j_[key].is_number_integer()) return fail(key, "expected an integer"), fallback;
    return j_[key].get<Int>();
  }
  template <class Int>
  std::optional<Int> opt_integer(const char* key) {
    if (!present(key) || j_[key].is_null()) return std::nullopt;
    if (!j_[key].is_number_integer()) return fail(key, "expected an integer or null"), std::nullopt;
    return j_[key].get<Int>();
  }
  std::string string(const char* key, std::string fallback) {
    if (!present(key) || j_[key].is_null()) return fallback;
    if (!j_[key].is_string()) return fail(key, "expected a string"), fallback;
    return j_[key].get<std::string>();
  }
  std::string required_string(const char* key) {
    if (!present(key) || !j_[key].is_string()) return fail(key, "expected a string"), std::string();
    return j_[key].get<std::string>();
  }

 private:
  bool present(const char* key) const { return j_.is_object() && j_.contains(key); }
  void fail(const char* key, const char* why) {
    if (error_.empty()) error_ = std::string(what_) + "." + key + ": " + why;
  }
  const json& j_;
  const char* what_;
  std::string error_;
};

}  // namespace

std::string_view to_string(ErrorCode c) {
  for (const auto& [code, text] : kCodes)
    if (code == c) return text;
  return "internal";
}

std::optional<ErrorCode> error_code_from_string(std::string_view s) {
  for (const auto& [code, text] : kCodes)
    if (text == s) return code;
  return std::nullopt;
}

json to_json(const Hello& h) {
  // max_line_bytes at the top level too: kept for clients of the first version.
  return {{"type", "hello"}, {"version", h.version}, {"protocol", h.protocol},
          {"max_line_bytes", h.max_line_bytes},
          {"limits", {{"max_line_bytes", h.max_line_bytes}, {"max_depth", h.max_depth}}}};
}

std::expected<Hello, std::string> hello_from_json(const json& j) {
  if (!j.is_object() || j.value("type", json()) != "hello")
    return std::unexpected(std::string("the daemon did not say hello (its first line is not a \"hello\" message)"));
  if (!j.contains("protocol") || !j["protocol"].is_number_integer())
    return std::unexpected(std::string("the daemon's hello has no protocol version (field \"protocol\")"));
  Hello h;
  h.protocol = j["protocol"].get<int>();
  h.version = j.value("version", json()).is_string() ? j["version"].get<std::string>() : "?";
  if (h.protocol != kProtocolVersion)
    return std::unexpected("the daemon (fogbenchd " + h.version + ") speaks protocol " + std::to_string(h.protocol) +
                           ", this client speaks protocol " + std::to_string(kProtocolVersion) +
                           ": use a fogctl of the daemon's release");
  const json& limits = j.value("limits", json::object());
  if (limits.is_object() && limits.contains("max_line_bytes") && limits["max_line_bytes"].is_number_unsigned())
    h.max_line_bytes = limits["max_line_bytes"].get<std::size_t>();
  if (limits.is_object() && limits.contains("max_depth") && limits["max_depth"].is_number_unsigned())
    h.max_depth = limits["max_depth"].get<std::size_t>();
  return h;
}

json number_or_null(std::optional<double> v) {
  if (!v || !std::isfinite(*v)) return nullptr;
  return *v;
}

namespace {
// A three-axis unit's y and z: fields of its samples only, so that a one-axis unit's keep their
// fields as before (the golden transcripts, clients that list fields).
void put_axes(json& j, bool three_axis, std::optional<double> y_dph, std::optional<double> z_dph) {
  if (!three_axis) return;
  j["gyro_y_dph"] = number_or_null(y_dph);
  j["gyro_z_dph"] = number_or_null(z_dph);
}
// Per-axis coil thermistors, likewise only on the samples of a unit that has them.
template <class S>
void put_axis_thermistors(json& j, const S& s) {
  if (!s.axis_thermistors) return;
  j["t1_y_c"] = number_or_null(s.t1_y_c);
  j["t2_y_c"] = number_or_null(s.t2_y_c);
  j["t1_z_c"] = number_or_null(s.t1_z_c);
  j["t2_z_c"] = number_or_null(s.t2_z_c);
}
template <class S>
void read_axis_thermistors(const json& j, Reader& r, S& s) {
  s.axis_thermistors = j.contains("t1_y_c") || j.contains("t2_y_c") || j.contains("t1_z_c") || j.contains("t2_z_c");
  s.t1_y_c = r.opt_number("t1_y_c");
  s.t2_y_c = r.opt_number("t2_y_c");
  s.t1_z_c = r.opt_number("t1_z_c");
  s.t2_z_c = r.opt_number("t2_z_c");
}
}  // namespace

json to_json(const Sample& s) {
  json j = {{"t_s", s.t_s}, {"wall_time", number_or_null(s.wall_time)}, {"setpoint_c", number_or_null(s.setpoint_c)},
          {"chamber_c", number_or_null(s.chamber_c)}, {"gyro_dph", number_or_null(s.gyro_dph)},
          {"frames", s.frames ? json(*s.frames) : json(nullptr)}, {"t1_c", number_or_null(s.t1_c)},
          {"t2_c", number_or_null(s.t2_c)}, {"phase", s.phase}, {"step", s.step ? json(*s.step) : json(nullptr)},
          {"flags", s.flags}, {"since_power_on_s", number_or_null(s.since_power_on_s)},
          {"compensated_dph", number_or_null(s.compensated_dph)}};
  // The table's commanded rate only where a rate table ran: a run without one keeps the
  // sample's fields as before (the golden transcripts, clients that list fields).
  if (s.rate_in_dps) j["rate_in_dps"] = *s.rate_in_dps;
  put_axes(j, s.three_axis, s.gyro_y_dph, s.gyro_z_dph);
  put_axis_thermistors(j, s);
  return j;
}

std::expected<Sample, std::string> sample_from_json(const json& j) {
  if (!j.is_object()) return std::unexpected(std::string("sample: expected an object"));
  Reader r(j, "sample");
  Sample s;
  s.t_s = r.number("t_s");
  s.wall_time = r.opt_number("wall_time");
  s.setpoint_c = r.opt_number("setpoint_c");
  s.chamber_c = r.opt_number("chamber_c");
  s.gyro_dph = r.opt_number("gyro_dph");
  s.frames = r.opt_integer<std::int64_t>("frames");
  s.t1_c = r.opt_number("t1_c");
  s.t2_c = r.opt_number("t2_c");
  s.phase = r.string("phase", "unknown");
  s.step = r.opt_integer<int>("step");
  s.flags = r.integer<std::uint8_t>("flags", 0);
  s.since_power_on_s = r.opt_number("since_power_on_s");
  s.compensated_dph = r.opt_number("compensated_dph");
  s.rate_in_dps = r.opt_number("rate_in_dps");
  s.three_axis = j.contains("gyro_y_dph") || j.contains("gyro_z_dph");
  s.gyro_y_dph = r.opt_number("gyro_y_dph");
  s.gyro_z_dph = r.opt_number("gyro_z_dph");
  read_axis_thermistors(j, r, s);
  if (!r.ok()) return std::unexpected(r.error());
  return s;
}

json to_json(const SampleMessage& s) {
  json j = {{"type", "sample"}, {"run_id", s.run_id}, {"t_s", s.t_s}, {"state", s.state}, {"phase", s.phase},
            {"step", s.step}, {"elapsed_s", s.elapsed_s}, {"remaining_s", s.remaining_s},
            {"setpoint_c", s.setpoint_c}, {"chamber_c", number_or_null(s.chamber_c)}, {"unit", s.unit},
            {"serial", s.serial}, {"gyro_dph", number_or_null(s.gyro_dph)}, {"frames", s.frames},
            {"t1_c", number_or_null(s.t1_c)}, {"t2_c", number_or_null(s.t2_c)}, {"flags", s.flags},
            {"since_power_on_s", number_or_null(s.since_power_on_s)},
            {"compensated_dph", number_or_null(s.compensated_dph)}};
  // As in run.samples: only where a rate table ran (the golden transcripts of other runs as before).
  if (s.rate_in_dps) j["rate_in_dps"] = *s.rate_in_dps;
  put_axes(j, s.three_axis, s.gyro_y_dph, s.gyro_z_dph);
  put_axis_thermistors(j, s);
  return j;
}

std::expected<SampleMessage, std::string> sample_message_from_json(const json& j) {
  if (!j.is_object() || j.value("type", json()) != "sample")
    return std::unexpected(std::string("sample message: expected an object of type \"sample\""));
  Reader r(j, "sample");
  SampleMessage s;
  s.run_id = r.integer<std::int64_t>("run_id", 0);
  s.t_s = r.number("t_s");
  s.state = r.required_string("state");
  s.phase = r.required_string("phase");
  s.step = r.integer<std::size_t>("step", 0);
  s.elapsed_s = r.number("elapsed_s");
  s.remaining_s = r.number("remaining_s");
  s.setpoint_c = r.number("setpoint_c");
  s.chamber_c = r.opt_number("chamber_c");
  s.unit = r.integer<int>("unit", 0);
  s.serial = r.required_string("serial");
  s.gyro_dph = r.opt_number("gyro_dph");
  s.frames = r.integer<std::int64_t>("frames", 0);
  s.t1_c = r.opt_number("t1_c");
  s.t2_c = r.opt_number("t2_c");
  s.flags = r.integer<std::uint8_t>("flags", 0);
  s.since_power_on_s = r.opt_number("since_power_on_s");
  s.compensated_dph = r.opt_number("compensated_dph");
  s.rate_in_dps = r.opt_number("rate_in_dps");
  s.three_axis = j.contains("gyro_y_dph") || j.contains("gyro_z_dph");
  s.gyro_y_dph = r.opt_number("gyro_y_dph");
  s.gyro_z_dph = r.opt_number("gyro_z_dph");
  read_axis_thermistors(j, r, s);
  if (!r.ok()) return std::unexpected(r.error());
  return s;
}

json to_json(const EventMessage& e) {
  return {{"type", "event"}, {"run_id", e.run_id}, {"t_s", number_or_null(e.t_s)}, {"kind", e.kind},
          {"detail", e.detail}};
}

std::expected<EventMessage, std::string> event_message_from_json(const json& j) {
  if (!j.is_object() || j.value("type", json()) != "event")
    return std::unexpected(std::string("event message: expected an object of type \"event\""));
  Reader r(j, "event");
  EventMessage e;
  e.run_id = r.integer<std::int64_t>("run_id", 0);
  e.t_s = r.opt_number("t_s");
  e.kind = r.required_string("kind");
  if (j.contains("detail")) e.detail = j["detail"];
  if (!r.ok()) return std::unexpected(r.error());
  return e;
}

}  // namespace fogbench::protocol
