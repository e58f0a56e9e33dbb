// See rate_table.hpp.
#include "rate_table.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "fogbench/drivers/acutrol_dialect.hpp"
#include "shared_state.hpp"

namespace fogbench::mock {

namespace acutrol = drivers::acutrol;

namespace {

// Position moves are integrated in steps of this, s.
constexpr double position_step_s = 1e-3;

double wrap360(double deg) {
  double p = std::fmod(deg, 360.0);
  if (p < 0) p += 360.0;
  return p;
}

// The shortest signed way from `from` to `to`, deg (-180..180].
double shortest_deg(double from, double to) {
  double d = std::fmod(to - from, 360.0);
  if (d > 180.0) d -= 360.0;
  if (d <= -180.0) d += 360.0;
  return d;
}

std::string line(std::string text) { return text + std::string(acutrol::line_end); }

std::string error_line(int code, std::string_view text) { return line(acutrol::format_error(code, text)); }

}  // namespace

// ---- the dynamics ---------------------------------------------------------------------------

double RateTableSim::ripple_integral(double t0_s, double t1_s) const {
  const double w = 2.0 * std::numbers::pi * spec_.ripple_hz;
  if (w <= 0 || spec_.ripple_dps == 0) return 0.0;
  return spec_.ripple_dps / w * (std::cos(w * t0_s) - std::cos(w * t1_s));
}

double RateTableSim::rate_dps() const noexcept {
  if (std::fabs(rate_dps_) <= spec_.standstill_dps) return rate_dps_;
  return rate_dps_ + spec_.ripple_dps * std::sin(2.0 * std::numbers::pi * spec_.ripple_hz * t_s_);
}

double RateTableSim::position_deg() const noexcept { return wrap360(position_deg_); }

void RateTableSim::step_rate(double dt_s, double target_dps, double accel_dps2) {
  // Exact for a rate reaching its target at a constant acceleration, then holding it.
  while (dt_s > 0) {
    const double diff = target_dps - rate_dps_;
    if (diff == 0) {
      position_deg_ += rate_dps_ * dt_s;
      return;
    }
    const double reach_s = std::fabs(diff) / accel_dps2;
    const double h = std::min(dt_s, reach_s);
    const double dv = h == reach_s ? diff : std::copysign(accel_dps2 * h, diff);
    position_deg_ += (rate_dps_ + 0.5 * dv) * h;
    rate_dps_ = h == reach_s ? target_dps : rate_dps_ + dv;
    dt_s -= h;
  }
}

void RateTableSim::step_position(double dt_s) {
  // Toward the demand along the shortest way: top speed the slew rate, braking at the
  // acceleration so as to stop on it.
  while (dt_s > 0) {
    const double h = std::min(dt_s, position_step_s);
    const double err = shortest_deg(position_deg_, demand_position_deg_);
    const double a = accel_dps2_;
    if (std::fabs(err) < 1e-9 && std::fabs(rate_dps_) <= a * h) {
      position_deg_ += err;
      rate_dps_ = 0;
      return;  // at rest on the demand: nothing more moves
    }
    const double want = std::copysign(std::min(spec_.position_slew_dps, std::sqrt(2.0 * a * std::fabs(err))), err);
    const double dv = std::clamp(want - rate_dps_, -a * h, a * h);
    double move = (rate_dps_ + 0.5 * dv) * h;
    rate_dps_ += dv;
    // Never step past the demand: land on it instead.
    if ((err > 0 && move > err) || (err < 0 && move < err)) {
      move = err;
      if (std::fabs(rate_dps_) <= a * h * 2) rate_dps_ = 0;
    }
    position_deg_ += move;
    dt_s -= h;
  }
}

void RateTableSim::advance_to(double t_s) {
  if (!(t_s > t_s_)) return;
  const double t0 = t_s_;
  const bool moving_before = std::fabs(rate_dps_) > spec_.standstill_dps;
  switch (mode_) {
    case Mode::rate: step_rate(t_s - t0, demand_rate_dps_, accel_dps2_); break;
    case Mode::position: step_position(t_s - t0); break;
    // Off (or held by a fault): the table brakes to rest at its acceleration limit.
    case Mode::off: step_rate(t_s - t0, 0.0, spec_.max_accel_dps2); break;
  }
  if (moving_before || std::fabs(rate_dps_) > spec_.standstill_dps) position_deg_ += ripple_integral(t0, t_s);
  t_s_ = t_s;
}

void RateTableSim::set_fault_condition(bool on, std::string text) {
  fault_condition_ = on;
  if (!on) return;
  if (!fault_latched_) fault_text_ = text.empty() ? "AMPLIFIER FAULT" : std::move(text);
  fault_latched_ = true;
  interlock_closed_ = false;
  mode_ = Mode::off;
}

unsigned RateTableSim::status_word() const noexcept {
  unsigned w = 0;
  if (interlock_closed_) w |= acutrol::status_interlock_closed;
  if (std::fabs(rate_dps_) > spec_.standstill_dps) w |= acutrol::status_moving;
  if (mode_ == Mode::rate) {
    w |= acutrol::status_mode_rate;
    if (rate_dps_ == demand_rate_dps_) w |= acutrol::status_at_rate;
  }
  if (mode_ == Mode::position) {
    w |= acutrol::status_mode_position;
    if (rate_dps_ == 0 && shortest_deg(position_deg_, demand_position_deg_) == 0) w |= acutrol::status_in_position;
  }
  if (fault_latched_) w |= acutrol::status_fault;
  return w;
}

std::string RateTableSim::answer(std::string_view text) {
  std::string why;
  auto cmd = acutrol::parse_command(text, &why);
  if (!cmd) return error_line(acutrol::err_syntax, "SYNTAX: " + why);
  if (cmd->axis != 1) return error_line(acutrol::err_syntax, "NO AXIS " + std::to_string(cmd->axis));
  const std::string ok = line(std::string(acutrol::ok_reply));
  // Motion needs the motor powered and no fault holding the table.
  auto may_move = [&]() -> std::optional<std::string> {
    if (fault_latched_) return error_line(acutrol::err_fault_active, "FAULT ACTIVE: " + fault_text_);
    if (!interlock_closed_) return error_line(acutrol::err_interlock_open, "INTERLOCK OPEN");
    return std::nullopt;
  };
  using V = acutrol::Verb;
  using I = acutrol::Item;
  switch (cmd->verb) {
    case V::read:
      switch (cmd->item) {
        case I::rate: return line(acutrol::format_number6(rate_dps()));
        case I::position: return line(acutrol::format_number6(position_deg()));
        case I::acceleration: return line(acutrol::format_number6(accel_dps2_));
        case I::status: return line(std::to_string(status_word()));
        case I::fault: return line(fault_latched_ ? fault_text_ : std::string(acutrol::no_fault));
        default: break;
      }
      break;
    case V::mode:
      if (cmd->item == I::off) {
        mode_ = Mode::off;
        return ok;
      }
      if (auto refused = may_move()) return *refused;
      if (cmd->item == I::rate && mode_ != Mode::rate) {
        mode_ = Mode::rate;
        demand_rate_dps_ = rate_dps_;  // bumpless: hold the rate it has
      } else if (cmd->item == I::position && mode_ != Mode::position) {
        mode_ = Mode::position;
        demand_position_deg_ = position_deg_;  // brake and hold where it is
      }
      return ok;
    case V::demand: {
      const double v = *cmd->value;
      if (cmd->item == I::acceleration) {
        if (!(v > 0 && v <= spec_.max_accel_dps2)) {
          return error_line(acutrol::err_accel_limit,
                            "ACCELERATION LIMIT " + acutrol::format_number6(spec_.max_accel_dps2));
        }
        accel_dps2_ = v;
        return ok;
      }
      if (auto refused = may_move()) return *refused;
      if (cmd->item == I::rate) {
        if (mode_ != Mode::rate) return error_line(acutrol::err_wrong_mode, "NOT IN RATE MODE");
        if (std::fabs(v) > spec_.max_rate_dps) {
          return error_line(acutrol::err_rate_limit, "RATE LIMIT EXCEEDED, MAX " + acutrol::format_number6(spec_.max_rate_dps));
        }
        demand_rate_dps_ = v;
        return ok;
      }
      if (mode_ != Mode::position) return error_line(acutrol::err_wrong_mode, "NOT IN POSITION MODE");
      demand_position_deg_ = position_deg_ + shortest_deg(position_deg_, v);
      return ok;
    }
    case V::interlock:
      if (cmd->item == I::open) {
        interlock_closed_ = false;
        mode_ = Mode::off;
        return ok;
      }
      if (cmd->item == I::reset) {
        if (fault_condition_) return error_line(acutrol::err_fault_active, "FAULT STILL PRESENT: " + fault_text_);
        fault_latched_ = false;
        fault_text_.clear();
        return ok;
      }
      if (fault_latched_) return error_line(acutrol::err_fault_active, "FAULT ACTIVE: " + fault_text_);
      interlock_closed_ = true;
      return ok;
  }
  return error_line(acutrol::err_syntax, "SYNTAX: not answered");
}

// ---- the listener ---------------------------------------------------------------------------

RateTableServer::RateTableServer(SharedState& shared, std::string host, int port, std::function<double()> now_s)
    : shared_(shared), now_s_(std::move(now_s)),
      lines_("rate table", std::move(host), port, [this](const std::string& line) { return answer(line); }) {}

LineServer::Reply RateTableServer::answer(const std::string& line) {
  std::lock_guard lock(shared_.mutex);
  auto& table = *shared_.rate_table;
  table.advance_to(now_s_());
  table.set_fault_condition(shared_.faults.table_fault, shared_.faults.table_fault_text);
  return {table.answer(line), 0};
}

void RateTableServer::watch(PollSet& set) {
  std::uint64_t drops = 0;
  {
    std::lock_guard lock(shared_.mutex);
    drops = shared_.faults.table_drops;
  }
  if (drops != drops_seen_) {
    drops_seen_ = drops;
    lines_.drop_clients();
  }
  (void)lines_.watch(set);  // its replies are never held back (no stall fault on the table)
}

}  // namespace fogbench::mock
