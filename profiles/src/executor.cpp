// The profile executor: turns (elapsed time, readings) into the setpoint to command, and
// judges settles by band, slope and the time they have held.
#include "fogbench/profiles/executor.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>

#include "detail.hpp"

namespace fogbench::profiles {

using detail::format_fixed;
using detail::format_number;

Executor::Executor(Profile profile) : profile_(std::move(profile)) {
  // parse_profile guarantees a leading setpoint; a hand-built profile without one is a bug.
  assert(!profile_.steps.empty() && profile_.steps.front().kind() == StepKind::setpoint);
  const auto planned = detail::plan(profile_);
  const std::size_t n = planned.size();
  start_setpoint_c_.resize(n);
  nominal_s_.resize(n);
  nominal_after_s_.assign(n, 0.0);
  phase_.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    start_setpoint_c_[i] = planned[i].start_setpoint_c;
    nominal_s_[i] = planned[i].duration_s;
    phase_[i] = planned[i].phase;
  }
  for (std::size_t i = n; i-- > 1;) nominal_after_s_[i - 1] = nominal_after_s_[i] + nominal_s_[i];
  if (n == 0) finished_ = true;
}

void Executor::begin_step(std::size_t index, double start_s) {
  if (index >= profile_.steps.size()) {
    // Keep index_ and step_start_s_ on the last step: the status reports it once finished.
    finished_ = true;
    return;
  }
  index_ = index;
  step_start_s_ = start_s;
  stable_since_s_.reset();
}

std::optional<double> Executor::slope_c_per_min(std::size_t channel) const {
  // Least squares over the finite readings of the window: slope = Sxy / Sxx. Time is taken
  // relative to the window's first sample so that large elapsed times lose no precision.
  const double t0_s = history_.empty() ? 0.0 : history_.front().time_s;
  double n = 0.0, st = 0.0, sv = 0.0;
  double t_min = std::numeric_limits<double>::infinity(), t_max = -t_min;
  for (const Sample& s : history_) {
    const double v = s.values_c[channel];
    if (!std::isfinite(v)) continue;
    const double t = s.time_s - t0_s;
    n += 1.0;
    st += t;
    sv += v;
    t_min = std::min(t_min, t);
    t_max = std::max(t_max, t);
  }
  if (n < 2.0 || t_max - t_min < slope_min_span_s) return std::nullopt;
  const double t_mean = st / n, v_mean = sv / n;
  double sxy = 0.0, sxx = 0.0;
  for (const Sample& s : history_) {
    const double v = s.values_c[channel];
    if (!std::isfinite(v)) continue;
    const double dt = s.time_s - t0_s - t_mean;
    sxy += dt * (v - v_mean);
    sxx += dt * dt;
  }
  return sxy / sxx * 60.0;  // degC/s -> degC/min
}

bool Executor::settled_now(const SettleStep& s, const Readings& r, std::string* why_not) const {
  auto no = [&](std::string why) {
    if (why_not != nullptr) *why_not = std::move(why);
    return false;
  };
  // Channel numbering matches Sample::values_c: 0 the chamber, then t1, t2 of every unit.
  // Names are only built for a message, not at every call.
  struct Channel {
    std::size_t index;
    double value_c;
  };
  auto name = [](std::size_t index) {
    if (index == 0) return std::string("chamber");
    const std::size_t unit = (index - 1) / 2;
    return "unit " + std::to_string(unit) +
           (index % 2 == 1 ? " coil centre (T1)" : " coil outer wall (T2)");
  };
  std::vector<Channel> channels;
  if (s.on == SettleOn::chamber) {
    channels.push_back({0, r.chamber_c});
  } else {
    if (r.coils.empty()) return no("no coil readings");
    for (std::size_t u = 0; u < r.coils.size(); ++u) {
      channels.push_back({1 + 2 * u, r.coils[u].t1_c});
      channels.push_back({2 + 2 * u, r.coils[u].t2_c});
    }
  }
  // Band first: it is the criterion an engineer checks first when a settle does not end.
  for (const Channel& c : channels) {
    // A missing reading proves nothing about stability, so it counts as out of band.
    if (!std::isfinite(c.value_c)) return no(name(c.index) + " has no reading");
    const double off_c = std::abs(c.value_c - setpoint_c_);
    if (!(off_c <= s.band_c)) {
      return no(name(c.index) + " " + format_fixed(c.value_c, 3) + " degC is " + format_fixed(off_c, 3) +
                " degC from the setpoint " + format_number(setpoint_c_) + " degC (band " +
                format_number(s.band_c) + " degC)");
    }
  }
  if (s.max_slope_c_per_min) {
    for (const Channel& c : channels) {
      const auto slope = slope_c_per_min(c.index);
      if (!slope) {
        return no(name(c.index) + " slope not known yet (needs " + format_number(slope_min_span_s) +
                  " s of readings)");
      }
      if (!(std::abs(*slope) < *s.max_slope_c_per_min)) {
        return no(name(c.index) + " slope " + format_fixed(*slope, 4) + " degC/min is not under " +
                  format_number(*s.max_slope_c_per_min) + " degC/min");
      }
    }
  }
  return true;
}

ExecutorStatus Executor::update(double elapsed_s, const Readings& readings) {
  // Time going backwards is a caller bug; in a release build hold the last time instead.
  assert(std::isfinite(elapsed_s) && elapsed_s >= last_time_s_);
  const double t_s = (std::isfinite(elapsed_s) && elapsed_s > last_time_s_) ? elapsed_s
                                                                             : last_time_s_;
  last_time_s_ = t_s;
  if (finished_ || failed_) return status(t_s);

  // Keep the readings of the slope window, whatever the step, so that a settle that begins
  // after a hold can judge its slope at once.
  Sample sample{t_s, {readings.chamber_c}};
  for (const CoilTemps& c : readings.coils) {
    sample.values_c.push_back(c.t1_c);
    sample.values_c.push_back(c.t2_c);
  }
  // A change in the number of units changes what the channels mean: start the window anew.
  if (!history_.empty() && history_.back().values_c.size() != sample.values_c.size()) {
    history_.clear();
  }
  history_.push_back(std::move(sample));
  while (history_.front().time_s < t_s - slope_window_s) history_.pop_front();

  while (!finished_ && !failed_) {
    const Step& step = profile_.steps[index_];
    if (const auto* sp = std::get_if<SetpointStep>(&step.action)) {
      setpoint_c_ = sp->temp_c;
      begin_step(index_ + 1, step_start_s_);
    } else if (const auto* st = std::get_if<SettleStep>(&step.action)) {
      if (settled_now(*st, readings, nullptr)) {
        if (!stable_since_s_) stable_since_s_ = t_s;
      } else {
        stable_since_s_.reset();  // an overshoot restarts the soak
      }
      if (stable_since_s_ && t_s - *stable_since_s_ >= st->stable_s) {
        begin_step(index_ + 1, t_s);
        continue;
      }
      if (t_s - step_start_s_ >= st->timeout_s) {
        std::string why;
        if (settled_now(*st, readings, &why)) {
          why = "met for only " + format_fixed(t_s - *stable_since_s_, 1) + " s of the " +
                format_number(st->stable_s) + " s it needs";
        }
        failed_ = true;
        failure_reason_ = "settle on line " + std::to_string(step.line) + " timed out after " +
                          format_number(st->timeout_s) + " s: " + why;
      }
      break;
    } else {
      // hold or ramp: both end at an exact time, which keeps the timeline independent of
      // when update() happens to be called.
      const double end_s = step_start_s_ + nominal_s_[index_];
      if (t_s >= end_s) {
        if (const auto* r = std::get_if<RampStep>(&step.action)) setpoint_c_ = r->target_c;
        begin_step(index_ + 1, end_s);
        continue;
      }
      if (const auto* r = std::get_if<RampStep>(&step.action)) {
        const double from_c = start_setpoint_c_[index_];
        const double direction = r->target_c >= from_c ? 1.0 : -1.0;
        setpoint_c_ = from_c + direction * r->rate_c_per_min / 60.0 * (t_s - step_start_s_);
      }
      break;
    }
  }
  return status(t_s);
}

ExecutorStatus Executor::status(double now_s) const {
  ExecutorStatus s;
  s.setpoint_c = setpoint_c_;
  if (profile_.steps.empty()) {
    s.finished = true;
    return s;
  }
  s.step_index = index_;
  s.step_line = profile_.steps[index_].line;
  s.step_elapsed_s = now_s - step_start_s_;
  s.finished = finished_;
  s.failed = failed_;
  s.failure_reason = failure_reason_;
  if (finished_) {
    s.phase = Phase::hold;  // the chamber keeps the final setpoint
    return s;
  }
  s.phase = phase_[index_];
  if (failed_) return s;
  double left_s = 0.0;
  if (const auto* st = std::get_if<SettleStep>(&profile_.steps[index_].action)) {
    const double held_s = stable_since_s_ ? now_s - *stable_since_s_ : 0.0;
    left_s = st->stable_s - held_s;
  } else {
    left_s = nominal_s_[index_] - s.step_elapsed_s;
  }
  s.remaining_s = std::max(0.0, left_s) + nominal_after_s_[index_];
  return s;
}

}  // namespace fogbench::profiles
