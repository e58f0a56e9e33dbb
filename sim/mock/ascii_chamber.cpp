// See ascii_chamber.hpp.
#include "ascii_chamber.hpp"

#include <charconv>
#include <cmath>

#include "fogbench/drivers/chamber_dialects.hpp"

namespace fogbench::mock {

namespace espec = drivers::espec;
namespace simserv = drivers::simserv;

namespace {

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\r' || s.front() == '\n')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\r' || s.back() == '\n')) s.remove_suffix(1);
  return s;
}

std::optional<double> number(std::string_view s) {
  s = trim(s);
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  double v = 0;
  auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (s.empty() || ec != std::errc{} || end != s.data() + s.size() || !std::isfinite(v)) return std::nullopt;
  return v;
}

bool settable(double c) { return c >= ascii_setpoint_min_c && c <= ascii_setpoint_max_c; }

std::string espec_line(std::string text) { return text + std::string(espec::line_end); }

}  // namespace

std::optional<ChamberDialect> parse_chamber_dialect(std::string_view name) noexcept {
  if (name == "modbus") return ChamberDialect::modbus;
  if (name == "espec") return ChamberDialect::espec;
  if (name == "simserv") return ChamberDialect::simserv;
  return std::nullopt;
}

std::string_view to_string(ChamberDialect dialect) noexcept {
  switch (dialect) {
    case ChamberDialect::modbus: return "modbus";
    case ChamberDialect::espec: return "espec";
    case ChamberDialect::simserv: return "simserv";
  }
  return "?";
}

std::string answer_espec(std::string_view line, ChamberRegisters& chamber, bool refuse_setpoint) {
  line = trim(line);
  const double sp = chamber.setpoint_c(0.0);
  if (line == espec::cmd_type) return espec_line("T,P300,250.0");
  if (line == espec::cmd_temp) {
    return espec_line(simserv::format_value(chamber.process_value_c()) + "," + simserv::format_value(sp) + "," +
                      simserv::format_value(ascii_setpoint_max_c) + "," + simserv::format_value(ascii_setpoint_min_c));
  }
  const std::string mode = chamber.running() ? "CONSTANT" : "STANDBY";
  if (line == espec::cmd_mode) return espec_line(mode);
  if (line == espec::cmd_mon) {
    return espec_line(simserv::format_value(chamber.process_value_c()) + ",," + mode + "," +
                      (chamber.alarm() ? "1" : "0"));
  }
  if (line == espec::cmd_alarm) return espec_line(chamber.alarm() ? "1,1" : "0");
  // Settings: "TEMP, S20.0" and "MODE, CONSTANT"; the controller takes them with or without the
  // space after the comma.
  auto setting = [&](std::string_view name) -> std::optional<std::string_view> {
    if (!line.starts_with(name) || line.size() <= name.size() || line[name.size()] != ',') return std::nullopt;
    return trim(line.substr(name.size() + 1));
  };
  if (auto arg = setting("TEMP")) {
    if (arg->empty() || arg->front() != 'S') return espec_line("NA:PARA ERR");
    auto c = number(arg->substr(1));
    if (!c) return espec_line("NA:PARA ERR");
    if (refuse_setpoint || !settable(*c)) return espec_line("NA:DATA OUT OF RANGE");
    chamber.write_setpoint_c(*c);
    return espec_line("OK:TEMP,S" + simserv::format_value(*c));
  }
  if (auto arg = setting("MODE")) {
    if (*arg == "CONSTANT") {
      chamber.write_running(true);
    } else if (*arg == "STANDBY" || *arg == "OFF") {
      chamber.write_running(false);
    } else {
      return espec_line("NA:PARA ERR");
    }
    return espec_line("OK:MODE," + std::string(*arg));
  }
  return espec_line("NA:CMD ERR");
}

std::string answer_simserv(std::string_view line, ChamberRegisters& chamber, bool refuse_setpoint) {
  auto reply = [](int code, std::vector<std::string> values = {}) { return simserv::format_reply(code, values); };
  auto cmd = simserv::parse_command(trim(line));
  if (!cmd) return reply(simserv::err_unknown_command);
  if (cmd->chamber_index != 1) return reply(simserv::err_bad_parameters);
  const auto& a = cmd->args;
  const bool temp_var = !a.empty() && a[0] == std::to_string(simserv::temperature_variable);
  switch (cmd->number) {
    case simserv::cmd_get_info:
      return reply(simserv::ok, {"fogbench mock SIMSERV"});
    case simserv::cmd_get_value:
      if (a.size() != 1 || !temp_var) return reply(simserv::err_bad_parameters);
      return reply(simserv::ok, {simserv::format_value(chamber.process_value_c())});
    case simserv::cmd_get_setpoint:
      if (a.size() != 1 || !temp_var) return reply(simserv::err_bad_parameters);
      return reply(simserv::ok, {simserv::format_value(chamber.setpoint_c(0.0))});
    case simserv::cmd_set_setpoint: {
      if (a.size() != 2 || !temp_var) return reply(simserv::err_bad_parameters);
      auto c = number(a[1]);
      if (!c || refuse_setpoint || !settable(*c)) return reply(simserv::err_bad_parameters);
      chamber.write_setpoint_c(*c);
      return reply(simserv::ok);
    }
    case simserv::cmd_start_manual:
      if (a.size() != 2 || a[0] != "1" || (a[1] != "0" && a[1] != "1")) return reply(simserv::err_bad_parameters);
      chamber.write_running(a[1] == "1");
      return reply(simserv::ok);
    case simserv::cmd_get_status: {
      unsigned status = 1;
      if (chamber.running()) status |= simserv::status_running_bit;
      if (chamber.alarm()) status |= simserv::status_alarm_bit;
      return reply(simserv::ok, {std::to_string(status)});
    }
    default:
      return reply(simserv::err_unknown_command);
  }
}

// ---- the listener --------------------------------------------------------------------------

AsciiChamberServer::AsciiChamberServer(SharedState& shared, ChamberDialect dialect, std::string host, int port)
    : shared_(shared), dialect_(dialect),
      lines_("chamber", std::move(host), port, [this](const std::string& line) { return answer(line); }) {}

void AsciiChamberServer::update_listener() {
  std::lock_guard lock(shared_.mutex);
  lines_.refuse(shared_.faults.refuse[static_cast<std::size_t>(Device::chamber)]);
}

LineServer::Reply AsciiChamberServer::answer(const std::string& line) {
  std::lock_guard lock(shared_.mutex);
  const bool refuse = shared_.faults.refuse_setpoint;
  return {dialect_ == ChamberDialect::espec ? answer_espec(line, *shared_.chamber, refuse)
                                            : answer_simserv(line, *shared_.chamber, refuse),
          shared_.faults.stall_ms[static_cast<std::size_t>(Device::chamber)]};
}

}  // namespace fogbench::mock
