// Chamber controller driver: setpoint, process value, run/stop, alarm, status, bring-up.
#include "fogbench/drivers/chamber.hpp"

namespace fogbench::drivers {

bool BringUpReport::ok() const noexcept {
  for (const auto& c : checks) {
    if (!c.ok) return false;
  }
  return true;
}

std::string BringUpReport::to_string() const {
  std::string out;
  for (const auto& c : checks) {
    out += c.ok ? "ok   " : "FAIL ";
    out += c.name + ": " + c.detail + "\n";
  }
  return out;
}

ModbusChamber::ModbusChamber(ChamberConfig config, ModbusLink::Clock clock)
    : config_(std::move(config)), link_(config_.modbus, "chamber", std::move(clock)) {}

Result<void> ModbusChamber::write_setpoint_c(double temp_c) {
  const auto& lim = config_.setpoint_limits_c;
  if (!(temp_c >= lim.min_c && temp_c <= lim.max_c)) {
    return fail(ErrorCode::out_of_range, "chamber: setpoint " + format_number(temp_c) +
                                             " degC outside the configured limits " +
                                             format_number(lim.min_c) + ".." +
                                             format_number(lim.max_c) + " degC");
  }
  return link_.write_value(config_.map.setpoint, temp_c);
}

Result<double> ModbusChamber::read_setpoint_c() { return link_.read_value(config_.map.setpoint); }

Result<double> ModbusChamber::read_process_value_c() {
  return link_.read_value(config_.map.process_value);
}

Result<void> ModbusChamber::set_running(bool run) {
  const auto& r = config_.map.run;
  if (r.reg.function == RegisterFunction::coil) return link_.write_coil(r.reg.address, run);
  const std::uint16_t word = run ? r.on_value : r.off_value;
  return link_.write_registers(r.reg.address, std::span<const std::uint16_t>(&word, 1));
}

Result<bool> ModbusChamber::read_running() {
  const auto& r = config_.map.run;
  auto raw = link_.read_raw(r.reg);
  if (!raw) return std::unexpected(raw.error());
  if (r.reg.function == RegisterFunction::coil) return *raw != 0;
  if (*raw == r.on_value) return true;
  if (*raw == r.off_value) return false;
  return fail(ErrorCode::protocol, "chamber: run register " + r.reg.describe() + " reads " +
                                       std::to_string(*raw) + ", neither on (" +
                                       std::to_string(r.on_value) + ") nor off (" +
                                       std::to_string(r.off_value) + ")");
}

Result<bool> ModbusChamber::read_alarm() {
  auto raw = link_.read_raw(config_.map.alarm.reg);
  if (!raw) return std::unexpected(raw.error());
  return (*raw & config_.map.alarm.mask) != 0;
}

Result<ChamberStatusWord> ModbusChamber::read_status() {
  if (!config_.map.status) {
    return fail(ErrorCode::config, "chamber: the map '" + config_.map.name + "' has no status register");
  }
  auto raw = link_.read_raw(config_.map.status->reg);
  if (!raw) return std::unexpected(raw.error());
  ChamberStatusWord word;
  word.raw = *raw;
  for (const auto& [name, bit] : config_.map.status->bits) {
    word.bits.emplace_back(name, ((*raw >> bit) & 1u) != 0);
  }
  return word;
}

Result<ChamberReading> ModbusChamber::poll() {
  ChamberReading r;
  auto pv = read_process_value_c();
  if (!pv) return std::unexpected(pv.error());
  r.process_value_c = *pv;
  auto sp = read_setpoint_c();
  if (!sp) return std::unexpected(sp.error());
  r.setpoint_c = *sp;
  auto running = read_running();
  if (!running) return std::unexpected(running.error());
  r.running = *running;
  auto alarm = read_alarm();
  if (!alarm) return std::unexpected(alarm.error());
  r.alarm = *alarm;
  if (config_.map.status) {
    auto status = read_status();
    if (!status) return std::unexpected(status.error());
    r.status = std::move(*status);
  }
  return r;
}

Result<BringUpReport> ModbusChamber::bring_up() {
  if (auto ok = link_.connect(); !ok) return std::unexpected(ok.error());
  BringUpReport report;
  report.checks.push_back({"connection", true, link_.endpoint().describe()});

  // A read that fails at the link ends the bring-up; one the device refuses (an exception for a
  // register it does not have) is a failed check and the others still run.
  auto checked = [&](const char* name, const CheckedSpec& spec) -> Result<void> {
    auto raw = link_.read_raw(spec.reg);
    if (!raw) {
      if (is_link_failure(raw.error())) return std::unexpected(raw.error());
      report.checks.push_back({name, false, raw.error().to_string()});
      return {};
    }
    BringUpCheck c{name, true, std::to_string(*raw) + " at " + spec.reg.describe()};
    if (spec.expect) {
      c.ok = *raw == *spec.expect;
      c.detail += " (expected " + std::to_string(*spec.expect) + ")";
    }
    report.checks.push_back(std::move(c));
    return {};
  };
  if (config_.map.identity) {
    if (auto ok = checked("identity", *config_.map.identity); !ok) return std::unexpected(ok.error());
  }
  if (config_.map.units) {
    if (auto ok = checked("units", *config_.map.units); !ok) return std::unexpected(ok.error());
  }

  const auto& lim = config_.pv_limits_c;
  if (auto pv = read_process_value_c(); pv) {
    const bool plausible = *pv >= lim.min_c && *pv <= lim.max_c;
    report.checks.push_back({"process_value", plausible,
                             format_number(*pv) + " degC (plausible " + format_number(lim.min_c) +
                                 ".." + format_number(lim.max_c) + " degC)"});
  } else if (is_link_failure(pv.error())) {
    return std::unexpected(pv.error());
  } else {
    report.checks.push_back({"process_value", false, pv.error().to_string()});
  }

  if (auto sp = read_setpoint_c(); sp) {
    report.checks.push_back({"setpoint", true, format_number(*sp) + " degC"});
  } else if (is_link_failure(sp.error())) {
    return std::unexpected(sp.error());
  } else {
    report.checks.push_back({"setpoint", false, sp.error().to_string()});
  }

  if (auto running = read_running(); running) {
    report.checks.push_back({"run", true, *running ? "running" : "stopped"});
  } else if (is_link_failure(running.error())) {
    return std::unexpected(running.error());
  } else {
    report.checks.push_back({"run", false, running.error().to_string()});
  }

  // An active alarm at bring-up fails the check: a run must not start on an alarmed chamber.
  if (auto alarm = read_alarm(); alarm) {
    report.checks.push_back({"alarm", !*alarm, *alarm ? "active" : "inactive"});
  } else if (is_link_failure(alarm.error())) {
    return std::unexpected(alarm.error());
  } else {
    report.checks.push_back({"alarm", false, alarm.error().to_string()});
  }

  if (config_.map.status) {
    if (auto status = read_status(); status) {
      std::string detail = "raw " + std::to_string(status->raw);
      for (const auto& [name, on] : status->bits) detail += std::string(" ") + name + "=" + (on ? "1" : "0");
      report.checks.push_back({"status", true, detail});
    } else if (is_link_failure(status.error())) {
      return std::unexpected(status.error());
    } else {
      report.checks.push_back({"status", false, status.error().to_string()});
    }
  }
  return report;
}

}  // namespace fogbench::drivers
