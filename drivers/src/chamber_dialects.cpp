// The Espec and SIMSERV dialects: command texts and reply parsing, shared by drivers and mock.
#include "fogbench/drivers/chamber_dialects.hpp"

#include <charconv>
#include <cmath>
#include <cstdio>

namespace fogbench::drivers {

namespace {

std::vector<std::string_view> split(std::string_view text, char sep) {
  std::vector<std::string_view> out;
  std::size_t start = 0;
  while (true) {
    const auto at = text.find(sep, start);
    out.push_back(text.substr(start, at == std::string_view::npos ? std::string_view::npos : at - start));
    if (at == std::string_view::npos) break;
    start = at + 1;
  }
  return out;
}

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
  return s;
}

std::optional<double> to_double(std::string_view s) {
  s = trim(s);
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  double v = 0;
  auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (s.empty() || ec != std::errc{} || end != s.data() + s.size() || !std::isfinite(v)) return std::nullopt;
  return v;
}

std::optional<int> to_int(std::string_view s) {
  s = trim(s);
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  int v = 0;
  auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (s.empty() || ec != std::errc{} || end != s.data() + s.size()) return std::nullopt;
  return v;
}

std::string one_decimal(double value) {
  char buf[32];
  // 0.1 degC is the controllers' resolution; -0.0 shows as 0.0.
  const double rounded = std::round(value * 10.0) / 10.0;
  std::snprintf(buf, sizeof buf, "%.1f", rounded == 0.0 ? 0.0 : rounded);
  return buf;
}

}  // namespace

std::string printable(std::string_view line) {
  std::string out;
  for (unsigned char c : line) {
    if (c >= 0x20 && c < 0x7f) {
      out += static_cast<char>(c);
    } else {
      char buf[8];
      std::snprintf(buf, sizeof buf, "<%02X>", c);
      out += buf;
    }
  }
  return out;
}

namespace espec {

std::string set_temp_command(double setpoint_c) { return "TEMP, S" + one_decimal(setpoint_c); }

std::string mode_command(bool run) { return run ? "MODE, CONSTANT" : "MODE, STANDBY"; }

std::optional<TempReply> parse_temp(std::string_view reply) {
  const auto f = split(reply, ',');
  if (f.size() != 4) return std::nullopt;
  TempReply r;
  double* targets[] = {&r.process_value_c, &r.setpoint_c, &r.upper_alarm_c, &r.lower_alarm_c};
  for (std::size_t i = 0; i < 4; ++i) {
    auto v = to_double(f[i]);
    if (!v) return std::nullopt;
    *targets[i] = *v;
  }
  return r;
}

std::optional<MonReply> parse_mon(std::string_view reply) {
  const auto f = split(reply, ',');
  if (f.size() != 4) return std::nullopt;
  MonReply r;
  auto t = to_double(f[0]);
  if (!t) return std::nullopt;
  r.temp_c = *t;
  if (!trim(f[1]).empty()) {
    auto h = to_double(f[1]);
    if (!h) return std::nullopt;
    r.humidity_pct = *h;
  }
  r.mode = std::string(trim(f[2]));
  if (!parse_mode(r.mode)) return std::nullopt;
  auto a = to_int(f[3]);
  if (!a || *a < 0) return std::nullopt;
  r.alarms = *a;
  return r;
}

std::optional<std::vector<int>> parse_alarm(std::string_view reply) {
  const auto f = split(reply, ',');
  auto n = to_int(f[0]);
  if (!n || *n < 0 || static_cast<std::size_t>(*n) != f.size() - 1) return std::nullopt;
  std::vector<int> codes;
  for (std::size_t i = 1; i < f.size(); ++i) {
    auto c = to_int(f[i]);
    if (!c) return std::nullopt;
    codes.push_back(*c);
  }
  return codes;
}

std::optional<Mode> parse_mode(std::string_view reply) {
  reply = trim(reply);
  if (reply == "OFF") return Mode::off;
  if (reply == "STANDBY") return Mode::standby;
  if (reply == "CONSTANT") return Mode::constant;
  if (reply == "RUN" || reply.starts_with("RUN ") || reply.starts_with("RMT RUN")) return Mode::run;
  return std::nullopt;
}

std::string_view to_string(Mode mode) noexcept {
  switch (mode) {
    case Mode::off: return "OFF";
    case Mode::standby: return "STANDBY";
    case Mode::constant: return "CONSTANT";
    case Mode::run: return "RUN";
  }
  return "?";
}

std::string_view describe_error(std::string_view code) noexcept {
  struct Entry {
    std::string_view code, meaning;
  };
  static constexpr Entry table[] = {
      {"CMD ERR", "unrecognized command"},
      {"ADDR ERR", "bad address"},
      {"PARA ERR", "parameter missing or unrecognizable"},
      {"DATA OUT OF RANGE", "data not within the valid range"},
      {"DATA NOT READY", "the data asked for does not exist"},
      {"PROTECT ON", "the controller's data protection is on"},
      {"CONT NOT READY-3", "command not supported by this controller"},
      {"INVALID REQ", "unsupported function"},
      {"CHB NOT READY", "could not act on the command"},
  };
  code = trim(code);
  for (const auto& e : table) {
    if (e.code == code) return e.meaning;
  }
  return "no description";
}

}  // namespace espec

namespace simserv {

std::string_view describe_code(int code) noexcept {
  switch (code) {
    case ok: return "command accepted and executed";
    case err_unknown_command: return "command number not recognised";
    case err_bad_parameters: return "too few or incorrect parameters";
    case err_not_readable: return "data could not be read";
  }
  return "unknown return code";
}

std::string format_command(int number, int chamber_index, std::span<const std::string> args) {
  std::string out = std::to_string(number);
  out += separator;
  out += std::to_string(chamber_index);
  for (const auto& a : args) {
    out += separator;
    out += a;
  }
  out += terminator;
  return out;
}

std::optional<Reply> parse_reply(std::string_view line) {
  const auto f = split(line, separator);
  auto code = to_int(f[0]);
  if (!code) return std::nullopt;
  Reply r;
  r.code = *code;
  for (std::size_t i = 1; i < f.size(); ++i) r.values.emplace_back(f[i]);
  return r;
}

std::optional<Command> parse_command(std::string_view line) {
  const auto f = split(line, separator);
  if (f.size() < 2) return std::nullopt;
  auto number = to_int(f[0]);
  auto index = to_int(f[1]);
  if (!number || !index) return std::nullopt;
  Command c{*number, *index, {}};
  for (std::size_t i = 2; i < f.size(); ++i) c.args.emplace_back(f[i]);
  return c;
}

std::string format_reply(int code, std::span<const std::string> values) {
  std::string out = std::to_string(code);
  for (const auto& v : values) {
    out += separator;
    out += v;
  }
  out += "\r\n";
  return out;
}

std::string format_value(double value_c) { return one_decimal(value_c); }

}  // namespace simserv

}  // namespace fogbench::drivers
