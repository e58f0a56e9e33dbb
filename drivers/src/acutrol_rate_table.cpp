// Acutronic ACUTROL rate-table controller over its ASCII command set (TCP); see
// acutrol_rate_table.hpp.
#include "fogbench/drivers/acutrol_rate_table.hpp"

#include <cmath>

#include "fogbench/drivers/acutrol_dialect.hpp"
#include "fogbench/drivers/chamber_dialects.hpp"

namespace fogbench::drivers {

namespace {

RateTable::WallClock wall_or_system(RateTable::WallClock wall) {
  if (wall) return wall;
  return [] { return std::chrono::system_clock::now(); };
}

}  // namespace

AcutrolRateTable::AcutrolRateTable(RateTableConfig config, WallClock wall, MonotonicClock clock)
    : config_(std::move(config)),
      wall_(wall_or_system(std::move(wall))),
      link_(config_.line, config_.name + " acutrol", std::string(acutrol::line_end), '\n', std::move(clock)) {}

void AcutrolRateTable::record(RateTableEvent::Kind kind, std::string reason) {
  events_.push_back({kind, wall_(), link_.prefix(), std::move(reason)});
}

std::vector<RateTableEvent> AcutrolRateTable::take_events() {
  std::vector<RateTableEvent> out;
  out.swap(events_);
  return out;
}

std::unexpected<DriverError> AcutrolRateTable::refuse(ErrorCode code, std::string reason) {
  record(RateTableEvent::Kind::refused, reason);
  return fail(code, link_.prefix() + ": " + reason);
}

Result<std::string> AcutrolRateTable::command(const std::string& text) {
  auto reply = link_.exchange(text, text);
  if (!reply) {
    if (is_link_failure(reply.error())) {
      // What the controller was last told is unknown after a reconnection: say it again.
      mode_.reset();
      accel_sent_ = false;
      if (!link_down_) {
        link_down_ = true;
        std::string why = reply.error().message;
        if (const auto p = link_.prefix() + ": "; why.starts_with(p)) why.erase(0, p.size());
        record(RateTableEvent::Kind::link_lost, "link lost: " + why);  // `why` names the command
      }
    }
    return reply;
  }
  if (link_down_) {
    link_down_ = false;
    record(RateTableEvent::Kind::link_restored, "link restored at '" + text + "'");
  }
  if (auto err = acutrol::parse_error(*reply)) {
    const bool limit = err->code == acutrol::err_rate_limit || err->code == acutrol::err_accel_limit;
    return refuse(limit ? ErrorCode::out_of_range : ErrorCode::protocol,
                  "'" + text + "' refused by the controller: '" + printable(*reply) + "' (" +
                      std::string(acutrol::describe_error(err->code)) + ")");
  }
  return reply;
}

Result<void> AcutrolRateTable::setting(const std::string& text) {
  auto reply = command(text);
  if (!reply) return std::unexpected(reply.error());
  if (*reply != acutrol::ok_reply) {
    return fail(ErrorCode::protocol, link_.prefix() + ": '" + text + "' answered '" + printable(*reply) +
                                         "', not 'OK' (is the controller an ACUTROL?)");
  }
  return {};
}

Result<void> AcutrolRateTable::ensure_mode(RateTableMode mode) {
  if (mode_ == mode) return {};
  const auto text = mode == RateTableMode::rate       ? acutrol::mode_rate(config_.axis)
                    : mode == RateTableMode::position ? acutrol::mode_position(config_.axis)
                                                      : acutrol::mode_off(config_.axis);
  if (auto ok = setting(text); !ok) return ok;
  mode_ = mode;
  return {};
}

Result<void> AcutrolRateTable::ensure_acceleration() {
  if (accel_sent_) return {};
  if (auto ok = setting(acutrol::demand_acceleration(config_.axis, config_.limits.max_accel_dps2)); !ok) return ok;
  accel_sent_ = true;
  return {};
}

Result<void> AcutrolRateTable::set_rate_dps(double rate_dps) {
  const double max = config_.limits.max_rate_dps;
  if (!std::isfinite(rate_dps) || std::fabs(rate_dps) > max) {
    return refuse(ErrorCode::out_of_range, "rate " + format_number(rate_dps) + " deg/s beyond the configured limit +-" +
                                               format_number(max) + " deg/s (not sent)");
  }
  if (auto ok = ensure_mode(RateTableMode::rate); !ok) return ok;
  if (auto ok = ensure_acceleration(); !ok) return ok;
  return setting(acutrol::demand_rate(config_.axis, rate_dps));
}

Result<void> AcutrolRateTable::go_to_position_deg(double position_deg) {
  if (!std::isfinite(position_deg)) {
    return refuse(ErrorCode::out_of_range, "position " + format_number(position_deg) + " deg is not a number (not sent)");
  }
  double p = std::fmod(position_deg, 360.0);
  if (p < 0) p += 360.0;
  if (auto ok = ensure_mode(RateTableMode::position); !ok) return ok;
  if (auto ok = ensure_acceleration(); !ok) return ok;
  return setting(acutrol::demand_position(config_.axis, p));
}

Result<void> AcutrolRateTable::stop() {
  if (auto ok = ensure_mode(RateTableMode::rate); !ok) return ok;
  if (auto ok = ensure_acceleration(); !ok) return ok;
  return setting(acutrol::demand_rate(config_.axis, 0.0));
}

Result<void> AcutrolRateTable::reset_and_close() {
  if (auto ok = setting(acutrol::interlock_reset(config_.axis)); !ok) return ok;
  return setting(acutrol::interlock_close(config_.axis));
}

Result<RateTableStatus> AcutrolRateTable::read_status() {
  auto number = [&](const std::string& text, std::string_view what) -> Result<double> {
    auto reply = command(text);
    if (!reply) return std::unexpected(reply.error());
    auto v = acutrol::parse_number(*reply);
    if (!v) {
      return fail(ErrorCode::protocol, link_.prefix() + ": '" + text + "' answered '" + printable(*reply) +
                                           "', not " + std::string(what));
    }
    return *v;
  };
  const auto status_cmd = acutrol::read_status(config_.axis);
  auto word_reply = command(status_cmd);
  if (!word_reply) return std::unexpected(word_reply.error());
  auto word = acutrol::parse_status(*word_reply);
  if (!word) {
    return fail(ErrorCode::protocol, link_.prefix() + ": '" + status_cmd + "' answered '" + printable(*word_reply) +
                                         "', not a status word 0..65535");
  }
  RateTableStatus s;
  s.interlock_closed = (*word & acutrol::status_interlock_closed) != 0;
  s.moving = (*word & acutrol::status_moving) != 0;
  s.at_rate = (*word & acutrol::status_at_rate) != 0;
  s.in_position = (*word & acutrol::status_in_position) != 0;
  s.fault = (*word & acutrol::status_fault) != 0;
  s.mode = (*word & acutrol::status_mode_rate) != 0       ? RateTableMode::rate
           : (*word & acutrol::status_mode_position) != 0 ? RateTableMode::position
                                                          : RateTableMode::off;
  auto rate = number(acutrol::read_rate(config_.axis), "a rate in deg/s");
  if (!rate) return std::unexpected(rate.error());
  s.rate_dps = *rate;
  auto position = number(acutrol::read_position(config_.axis), "a position in deg");
  if (!position) return std::unexpected(position.error());
  s.position_deg = *position;
  if (s.fault) {
    auto text = command(acutrol::read_fault(config_.axis));
    if (!text) return std::unexpected(text.error());
    s.fault_text = *text;
    if (!fault_seen_) record(RateTableEvent::Kind::fault, "the table reports a fault: '" + printable(*text) + "'");
  } else if (fault_seen_) {
    record(RateTableEvent::Kind::fault_cleared, "the table's fault has cleared");
  }
  fault_seen_ = s.fault;
  // The controller leaves its mode on a fault (the interlock opens): say it again next time.
  if (s.mode != mode_) mode_.reset();
  return s;
}

}  // namespace fogbench::drivers
