// Weiss / Voetsch chamber controller over SIMSERV (TCP).
#include "fogbench/drivers/simserv_chamber.hpp"

#include <charconv>
#include <cmath>

#include "fogbench/drivers/chamber_dialects.hpp"

namespace fogbench::drivers {

namespace {

std::optional<double> simserv_number(const std::string& s) {
  double v = 0;
  auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (s.empty() || ec != std::errc{} || end != s.data() + s.size() || !std::isfinite(v)) return std::nullopt;
  return v;
}

// The command as messages show it: its fields with <B6> between them, without the CR.
std::string shown_command(int number, int chamber_index, const std::vector<std::string>& args) {
  const std::string command = simserv::format_command(number, chamber_index, args);
  return printable(std::string_view(command).substr(0, command.size() - 1));
}

}  // namespace

SimservChamber::SimservChamber(ChamberConfig config, LineLink::Clock clock)
    : config_(std::move(config)),
      // format_command ends each command with its CR; replies end at CR (a LF after it is skipped).
      link_(config_.line, "chamber simserv", "", simserv::terminator, std::move(clock)) {}

Result<std::vector<std::string>> SimservChamber::query(int number, std::vector<std::string> args) {
  const std::string command = simserv::format_command(number, config_.simserv_chamber_index, args);
  const std::string shown = shown_command(number, config_.simserv_chamber_index, args);
  auto line = link_.exchange(command, shown);
  if (!line) return std::unexpected(line.error());
  auto reply = simserv::parse_reply(*line);
  if (!reply) {
    return fail(ErrorCode::protocol, link_.prefix() + ": '" + shown + "' answered '" + printable(*line) +
                                         "', not a SIMSERV reply (a return code, then values separated "
                                         "by <B6>; is the controller on SIMSERV?)");
  }
  if (reply->code != simserv::ok) {
    return fail(ErrorCode::protocol, link_.prefix() + ": '" + shown + "' answered '" + printable(*line) +
                                         "': return code " + std::to_string(reply->code) + " (" +
                                         std::string(simserv::describe_code(reply->code)) + ")");
  }
  return std::move(reply->values);
}

Result<double> SimservChamber::read_number(int number, std::vector<std::string> args) {
  const std::string shown = shown_command(number, config_.simserv_chamber_index, args);
  auto values = query(number, std::move(args));
  if (!values) return std::unexpected(values.error());
  if (values->empty() || !simserv_number(values->front())) {
    std::string got;
    for (const auto& v : *values) got += "<B6>" + printable(v);
    return fail(ErrorCode::protocol, link_.prefix() + ": '" + shown + "' answered '1" + got +
                                         "', not a number");
  }
  return *simserv_number(values->front());
}

Result<ChamberStatusWord> SimservChamber::read_status() {
  auto raw = read_number(simserv::cmd_get_status, {});
  if (!raw) return std::unexpected(raw.error());
  ChamberStatusWord w;
  w.raw = static_cast<std::uint32_t>(*raw);
  w.bits = {{"running", (w.raw & simserv::status_running_bit) != 0},
            {"warnings", (w.raw & simserv::status_warning_bit) != 0},
            {"alarms", (w.raw & simserv::status_alarm_bit) != 0}};
  return w;
}

Result<void> SimservChamber::write_setpoint_c(double temp_c) {
  const auto& lim = config_.setpoint_limits_c;
  if (!(temp_c >= lim.min_c && temp_c <= lim.max_c)) {
    return fail(ErrorCode::out_of_range, link_.prefix() + ": setpoint " + format_number(temp_c) +
                                             " degC outside the configured limits " +
                                             format_number(lim.min_c) + ".." + format_number(lim.max_c) +
                                             " degC");
  }
  auto ok = query(simserv::cmd_set_setpoint,
                  {std::to_string(simserv::temperature_variable), simserv::format_value(temp_c)});
  if (!ok) return std::unexpected(ok.error());
  return {};
}

Result<void> SimservChamber::set_running(bool run) {
  auto ok = query(simserv::cmd_start_manual, {"1", run ? "1" : "0"});
  if (!ok) return std::unexpected(ok.error());
  return {};
}

Result<ChamberReading> SimservChamber::poll() {
  const std::string var = std::to_string(simserv::temperature_variable);
  auto pv = read_number(simserv::cmd_get_value, {var});
  if (!pv) return std::unexpected(pv.error());
  auto sp = read_number(simserv::cmd_get_setpoint, {var});
  if (!sp) return std::unexpected(sp.error());
  auto status = read_status();
  if (!status) return std::unexpected(status.error());
  ChamberReading r;
  r.process_value_c = *pv;
  r.setpoint_c = *sp;
  r.running = (status->raw & simserv::status_running_bit) != 0;
  r.alarm = (status->raw & simserv::status_alarm_bit) != 0;
  r.status = std::move(*status);
  return r;
}

Result<BringUpReport> SimservChamber::bring_up() {
  if (auto ok = link_.connect(); !ok) return std::unexpected(ok.error());
  BringUpReport report;
  report.checks.push_back({"connection", true, link_.endpoint().describe() + ", chamber index " +
                                                   std::to_string(config_.simserv_chamber_index)});
  // A command that fails at the link ends the bring-up; one the controller refuses or answers
  // in another dialect fails its check and the others still run.
  auto record = [&](const char* name, const DriverError& e) -> Result<void> {
    if (is_link_failure(e)) return std::unexpected(e);
    report.checks.push_back({name, false, e.to_string()});
    return {};
  };
  if (auto info = query(simserv::cmd_get_info, {}); info) {
    report.checks.push_back({"identity", !info->empty(), info->empty() ? "no type text" : printable(info->front())});
  } else if (auto r = record("identity", info.error()); !r) {
    return std::unexpected(r.error());
  }
  const std::string var = std::to_string(simserv::temperature_variable);
  const auto& lim = config_.pv_limits_c;
  if (auto pv = read_number(simserv::cmd_get_value, {var}); pv) {
    const bool plausible = *pv >= lim.min_c && *pv <= lim.max_c;
    report.checks.push_back({"process_value", plausible,
                             format_number(*pv) + " degC (plausible " + format_number(lim.min_c) + ".." +
                                 format_number(lim.max_c) + " degC)"});
  } else if (auto r = record("process_value", pv.error()); !r) {
    return std::unexpected(r.error());
  }
  if (auto sp = read_number(simserv::cmd_get_setpoint, {var}); sp) {
    report.checks.push_back({"setpoint", true, format_number(*sp) + " degC"});
  } else if (auto r = record("setpoint", sp.error()); !r) {
    return std::unexpected(r.error());
  }
  // An active alarm at bring-up fails the check: a run must not start on an alarmed chamber.
  if (auto st = read_status(); st) {
    const bool running = (st->raw & simserv::status_running_bit) != 0;
    const bool alarm = (st->raw & simserv::status_alarm_bit) != 0;
    report.checks.push_back({"run", true, running ? "running" : "stopped"});
    report.checks.push_back({"alarm", !alarm, alarm ? "active" : "inactive"});
    report.checks.push_back({"status", true, "raw " + std::to_string(st->raw)});
  } else if (auto r = record("status", st.error()); !r) {
    return std::unexpected(r.error());
  }
  return report;
}

}  // namespace fogbench::drivers
