// Espec P300 / SCP-220 chamber controller over its ASCII command set (TCP or serial).
#include "fogbench/drivers/espec_chamber.hpp"

namespace fogbench::drivers {

EspecChamber::EspecChamber(ChamberConfig config, LineLink::Clock clock)
    : config_(std::move(config)),
      link_(config_.line, "chamber espec", std::string(espec::line_end), '\n', std::move(clock)) {}

std::unexpected<DriverError> EspecChamber::unexpected_reply(std::string_view command, const std::string& reply,
                                                            std::string_view expected) {
  return fail(ErrorCode::protocol, link_.prefix() + ": '" + std::string(command) + "' answered '" +
                                       printable(reply) + "', not " + std::string(expected) +
                                       " (is the controller an Espec P300/SCP-220?)");
}

Result<std::string> EspecChamber::query(std::string_view command) {
  auto reply = link_.exchange(command, command);
  if (!reply) return reply;
  if (reply->starts_with(espec::error_prefix)) {
    const std::string code = reply->substr(espec::error_prefix.size());
    return fail(ErrorCode::protocol, link_.prefix() + ": '" + std::string(command) + "' refused: '" +
                                         printable(*reply) + "' (" +
                                         std::string(espec::describe_error(code)) + ")");
  }
  return reply;
}

Result<espec::TempReply> EspecChamber::read_temp() {
  auto reply = query(espec::cmd_temp);
  if (!reply) return std::unexpected(reply.error());
  auto temp = espec::parse_temp(*reply);
  if (!temp) return unexpected_reply(espec::cmd_temp, *reply, "'pv,setpoint,upper,lower' in degC");
  return *temp;
}

Result<espec::MonReply> EspecChamber::read_mon() {
  auto reply = query(espec::cmd_mon);
  if (!reply) return std::unexpected(reply.error());
  auto mon = espec::parse_mon(*reply);
  if (!mon) return unexpected_reply(espec::cmd_mon, *reply, "'temp,humidity,mode,alarms'");
  return *mon;
}

Result<void> EspecChamber::setting(const std::string& command, ErrorCode refused) {
  auto reply = link_.exchange(command, command);
  if (!reply) return std::unexpected(reply.error());
  if (reply->starts_with(espec::error_prefix)) {
    const std::string code = reply->substr(espec::error_prefix.size());
    const ErrorCode ec = code == "DATA OUT OF RANGE" ? refused : ErrorCode::protocol;
    return fail(ec, link_.prefix() + ": '" + command + "' refused: '" + printable(*reply) + "' (" +
                        std::string(espec::describe_error(code)) + ")");
  }
  if (!reply->starts_with(espec::ok_prefix)) return unexpected_reply(command, *reply, "'OK:...'");
  return {};
}

Result<void> EspecChamber::write_setpoint_c(double temp_c) {
  const auto& lim = config_.setpoint_limits_c;
  if (!(temp_c >= lim.min_c && temp_c <= lim.max_c)) {
    return fail(ErrorCode::out_of_range, link_.prefix() + ": setpoint " + format_number(temp_c) +
                                             " degC outside the configured limits " +
                                             format_number(lim.min_c) + ".." + format_number(lim.max_c) +
                                             " degC");
  }
  return setting(espec::set_temp_command(temp_c), ErrorCode::out_of_range);
}

Result<void> EspecChamber::set_running(bool run) {
  return setting(espec::mode_command(run), ErrorCode::protocol);
}

Result<ChamberReading> EspecChamber::poll() {
  auto temp = read_temp();
  if (!temp) return std::unexpected(temp.error());
  auto mon = read_mon();
  if (!mon) return std::unexpected(mon.error());
  ChamberReading r;
  r.process_value_c = temp->process_value_c;
  r.setpoint_c = temp->setpoint_c;
  const auto mode = espec::parse_mode(mon->mode);
  r.running = mode == espec::Mode::constant || mode == espec::Mode::run;
  r.alarm = mon->alarms > 0;
  return r;
}

Result<BringUpReport> EspecChamber::bring_up() {
  if (auto ok = link_.connect(); !ok) return std::unexpected(ok.error());
  BringUpReport report;
  report.checks.push_back({"connection", true, link_.endpoint().describe()});

  // A command that fails at the link ends the bring-up; one the controller refuses or answers
  // in another dialect fails its check and the others still run.
  auto check = [&](const char* name, auto&& read, auto&& judge) -> Result<void> {
    auto got = read();
    if (!got) {
      if (is_link_failure(got.error())) return std::unexpected(got.error());
      report.checks.push_back({name, false, got.error().to_string()});
      return {};
    }
    report.checks.push_back(judge(*got));
    return {};
  };
  auto type = check("identity", [&] { return query(espec::cmd_type); }, [&](const std::string& t) {
    // "T,S2,160.0" or "T,T,S2,160.0": sensors, controller, maximum degC.
    const bool looks = t.find(',') != std::string::npos && !t.starts_with(espec::ok_prefix);
    return BringUpCheck{"identity", looks, "TYPE? '" + printable(t) + "'" +
                                               (looks ? "" : " (not an Espec TYPE? reply)")};
  });
  if (!type) return std::unexpected(type.error());
  const auto& lim = config_.pv_limits_c;
  espec::TempReply temp;
  bool have_temp = false;
  auto t = check("process_value", [&] { return read_temp(); }, [&](const espec::TempReply& r) {
    temp = r;
    have_temp = true;
    const bool plausible = r.process_value_c >= lim.min_c && r.process_value_c <= lim.max_c;
    return BringUpCheck{"process_value", plausible,
                        format_number(r.process_value_c) + " degC (plausible " + format_number(lim.min_c) +
                            ".." + format_number(lim.max_c) + " degC)"};
  });
  if (!t) return std::unexpected(t.error());
  if (have_temp) report.checks.push_back({"setpoint", true, format_number(temp.setpoint_c) + " degC"});
  auto m = check("run", [&] { return read_mon(); }, [&](const espec::MonReply& r) {
    return BringUpCheck{"run", true, r.mode};
  });
  if (!m) return std::unexpected(m.error());
  // An active alarm at bring-up fails the check: a run must not start on an alarmed chamber.
  auto a = check("alarm", [&]() -> Result<std::vector<int>> {
    auto reply = query(espec::cmd_alarm);
    if (!reply) return std::unexpected(reply.error());
    auto codes = espec::parse_alarm(*reply);
    if (!codes) return unexpected_reply(espec::cmd_alarm, *reply, "'count,code,...'");
    return *codes;
  }, [&](const std::vector<int>& codes) {
    std::string detail = codes.empty() ? "inactive" : "active:";
    for (int c : codes) detail += " " + std::to_string(c);
    return BringUpCheck{"alarm", codes.empty(), detail};
  });
  if (!a) return std::unexpected(a.error());
  return report;
}

}  // namespace fogbench::drivers
