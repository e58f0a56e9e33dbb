// The ACUTROL rate-table command set: texts, replies, the status word; see acutrol_dialect.hpp.
#include "fogbench/drivers/acutrol_dialect.hpp"

#include <array>
#include <cctype>
#include <charconv>
#include <cmath>

namespace fogbench::drivers::acutrol {

namespace {

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t' || s.front() == '\r' || s.front() == '\n')) {
    s.remove_prefix(1);
  }
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r' || s.back() == '\n')) {
    s.remove_suffix(1);
  }
  return s;
}

std::string with_axis(std::string_view header, int axis) { return std::string(header) + " " + std::to_string(axis); }

std::string with_value(std::string_view header, int axis, double value) {
  return with_axis(header, axis) + ", " + format_number6(value);
}

// `word` is a non-empty prefix of `name`, any case.
bool abbreviates(std::string_view word, std::string_view name) {
  if (word.empty() || word.size() > name.size()) return false;
  for (std::size_t i = 0; i < word.size(); ++i) {
    if (std::tolower(static_cast<unsigned char>(word[i])) != name[i]) return false;
  }
  return true;
}

template <class T, std::size_t N>
std::optional<T> lookup(std::string_view word, const std::array<std::pair<std::string_view, T>, N>& names) {
  std::optional<T> found;
  for (const auto& [name, value] : names) {
    if (abbreviates(word, name)) {
      if (found) return std::nullopt;  // ambiguous
      found = value;
    }
  }
  return found;
}

}  // namespace

std::string_view describe_error(int code) noexcept {
  switch (code) {
    case err_syntax: return "not a command of the set, or its arguments do not parse";
    case err_rate_limit: return "rate demand beyond the table's rate limit";
    case err_accel_limit: return "acceleration demand beyond the table's limit";
    case err_fault_active: return "a fault holds the table (reset the interlock once it has gone)";
    case err_interlock_open: return "the interlock is open (motor power off)";
    case err_wrong_mode: return "the demand does not fit the current mode";
    default: return "no description";
  }
}

std::string format_number6(double value) {
  char buf[64];
  auto [end, ec] = std::to_chars(buf, buf + sizeof buf, value, std::chars_format::fixed, 6);
  if (ec != std::errc{}) return "nan";
  return std::string(buf, end);
}

std::string mode_rate(int axis) { return with_axis(":mode:rate", axis); }
std::string mode_position(int axis) { return with_axis(":mode:position", axis); }
std::string mode_off(int axis) { return with_axis(":mode:off", axis); }
std::string demand_rate(int axis, double rate_dps) { return with_value(":demand:rate", axis, rate_dps); }
std::string demand_position(int axis, double position_deg) {
  return with_value(":demand:position", axis, position_deg);
}
std::string demand_acceleration(int axis, double accel_dps2) {
  return with_value(":demand:acceleration", axis, accel_dps2);
}
std::string read_rate(int axis) { return with_axis(":read:rate", axis); }
std::string read_position(int axis) { return with_axis(":read:position", axis); }
std::string read_status(int axis) { return with_axis(":read:status", axis); }
std::string read_fault(int axis) { return with_axis(":read:fault", axis); }
std::string interlock_close(int axis) { return with_axis(":interlock:close", axis); }
std::string interlock_open(int axis) { return with_axis(":interlock:open", axis); }
std::string interlock_reset(int axis) { return with_axis(":interlock:reset", axis); }

std::optional<double> parse_number(std::string_view reply) {
  reply = trim(reply);
  if (!reply.empty() && reply.front() == '+') reply.remove_prefix(1);
  double v = 0;
  auto [end, ec] = std::from_chars(reply.data(), reply.data() + reply.size(), v);
  if (reply.empty() || ec != std::errc{} || end != reply.data() + reply.size() || !std::isfinite(v)) {
    return std::nullopt;
  }
  return v;
}

std::optional<unsigned> parse_status(std::string_view reply) {
  reply = trim(reply);
  unsigned v = 0;
  auto [end, ec] = std::from_chars(reply.data(), reply.data() + reply.size(), v);
  if (reply.empty() || ec != std::errc{} || end != reply.data() + reply.size() || v > 65535) return std::nullopt;
  return v;
}

std::optional<ErrorReply> parse_error(std::string_view reply) {
  reply = trim(reply);
  if (!reply.starts_with(error_prefix)) return std::nullopt;
  reply.remove_prefix(error_prefix.size());
  reply = trim(reply);
  int code = 0;
  auto [end, ec] = std::from_chars(reply.data(), reply.data() + reply.size(), code);
  if (ec != std::errc{}) return std::nullopt;
  std::string_view rest(end, static_cast<std::size_t>(reply.data() + reply.size() - end));
  rest = trim(rest);
  if (!rest.empty() && rest.front() == ':') rest.remove_prefix(1);
  return ErrorReply{code, std::string(trim(rest))};
}

std::string format_error(int code, std::string_view text) {
  return std::string(error_prefix) + " " + std::to_string(code) + ": " + std::string(text);
}

std::optional<Command> parse_command(std::string_view line, std::string* why) {
  auto refuse = [&](std::string text) -> std::optional<Command> {
    if (why != nullptr) *why = std::move(text);
    return std::nullopt;
  };
  line = trim(line);
  if (line.empty() || line.front() != ':') return refuse("a command starts with ':'");
  line.remove_prefix(1);
  const auto colon = line.find(':');
  if (colon == std::string_view::npos) return refuse("no second header node");
  const auto space = line.find(' ', colon);
  const std::string_view first = line.substr(0, colon);
  const std::string_view second = line.substr(colon + 1, space == std::string_view::npos ? std::string_view::npos
                                                                                           : space - colon - 1);
  static constexpr std::array<std::pair<std::string_view, Verb>, 4> verbs{{
      {"mode", Verb::mode}, {"demand", Verb::demand}, {"read", Verb::read}, {"interlock", Verb::interlock}}};
  auto verb = lookup(first, verbs);
  if (!verb) return refuse("unknown header ':" + std::string(first) + "'");
  std::optional<Item> item;
  switch (*verb) {
    case Verb::mode: {
      static constexpr std::array<std::pair<std::string_view, Item>, 3> items{{
          {"rate", Item::rate}, {"position", Item::position}, {"off", Item::off}}};
      item = lookup(second, items);
      break;
    }
    case Verb::demand: {
      static constexpr std::array<std::pair<std::string_view, Item>, 3> items{{
          {"rate", Item::rate}, {"position", Item::position}, {"acceleration", Item::acceleration}}};
      item = lookup(second, items);
      break;
    }
    case Verb::read: {
      static constexpr std::array<std::pair<std::string_view, Item>, 5> items{{
          {"rate", Item::rate}, {"position", Item::position}, {"acceleration", Item::acceleration},
          {"status", Item::status}, {"fault", Item::fault}}};
      item = lookup(second, items);
      break;
    }
    case Verb::interlock: {
      static constexpr std::array<std::pair<std::string_view, Item>, 3> items{{
          {"open", Item::open}, {"close", Item::close}, {"reset", Item::reset}}};
      item = lookup(second, items);
      break;
    }
  }
  if (!item) return refuse("unknown node ':" + std::string(second) + "' after ':" + std::string(first) + "'");
  Command cmd;
  cmd.verb = *verb;
  cmd.item = *item;
  std::string_view args = space == std::string_view::npos ? std::string_view{} : trim(line.substr(space + 1));
  const auto comma = args.find(',');
  const std::string_view axis_text = trim(args.substr(0, comma));
  auto [end, ec] = std::from_chars(axis_text.data(), axis_text.data() + axis_text.size(), cmd.axis);
  if (axis_text.empty() || ec != std::errc{} || end != axis_text.data() + axis_text.size()) {
    return refuse("expected an axis number, got '" + std::string(axis_text) + "'");
  }
  if (comma != std::string_view::npos) {
    auto v = parse_number(args.substr(comma + 1));
    if (!v) return refuse("expected a number after the axis, got '" + std::string(trim(args.substr(comma + 1))) + "'");
    cmd.value = *v;
  }
  if (cmd.verb == Verb::demand && !cmd.value) return refuse("a demand needs a value");
  if (cmd.verb != Verb::demand && cmd.value) return refuse("only a demand takes a value");
  return cmd;
}

}  // namespace fogbench::drivers::acutrol
