// The nominal plan of a profile and what is built on it: its duration, the nominal setpoint
// series and the chamber-limit check; plus the small formatting helpers for messages.
#include <array>
#include <cassert>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <type_traits>

#include "detail.hpp"
#include "fogbench/profiles/profile.hpp"

namespace fogbench::profiles {

// Step::kind() reads the variant's index; keep the enum in the variant's order.
static_assert(std::is_same_v<std::variant_alternative_t<0, decltype(Step::action)>, SetpointStep>);
static_assert(std::is_same_v<std::variant_alternative_t<1, decltype(Step::action)>, HoldStep>);
static_assert(std::is_same_v<std::variant_alternative_t<2, decltype(Step::action)>, RampStep>);
static_assert(std::is_same_v<std::variant_alternative_t<3, decltype(Step::action)>, SettleStep>);

std::string_view to_string(Phase p) {
  switch (p) {
    case Phase::settle: return "settle";
    case Phase::hold: return "hold";
    case Phase::heating: return "heating";
    case Phase::cooling: return "cooling";
  }
  return "?";
}

std::string_view to_string(StepKind k) {
  switch (k) {
    case StepKind::setpoint: return "setpoint";
    case StepKind::hold: return "hold";
    case StepKind::ramp: return "ramp";
    case StepKind::settle: return "settle";
  }
  return "?";
}

std::string ProfileError::to_string() const {
  if (line <= 0) return source + ": " + message;
  return source + ":" + std::to_string(line) + ":" + std::to_string(column) + ": " + message;
}

std::string ProfileError::excerpt() const {
  if (line <= 0) return {};
  std::string caret;
  // Copy the tabs before the column so the caret sits under the same character however a
  // terminal expands them.
  for (int i = 0; i + 1 < column; ++i) {
    const auto u = static_cast<std::size_t>(i);
    caret += (u < line_text.size() && line_text[u] == '\t') ? '\t' : ' ';
  }
  return line_text + "\n" + caret + "^";
}

namespace detail {

std::string format_number(double v) {
  std::array<char, 64> buf{};
  const auto r = std::to_chars(buf.data(), buf.data() + buf.size(), v);
  return std::string(buf.data(), r.ptr);
}

std::string format_fixed(double v, int decimals) {
  std::array<char, 64> buf{};
  const auto r =
      std::to_chars(buf.data(), buf.data() + buf.size(), v, std::chars_format::fixed, decimals);
  return std::string(buf.data(), r.ptr);
}

std::vector<PlannedStep> plan(const Profile& profile) {
  std::vector<PlannedStep> out;
  out.reserve(profile.steps.size());
  double t_s = 0.0;
  double sp_c = 0.0;  // steps[0] is a setpoint, so this initial value is never reported
  for (const Step& step : profile.steps) {
    PlannedStep p;
    p.start_s = t_s;
    p.start_setpoint_c = sp_c;
    if (const auto* s = std::get_if<SetpointStep>(&step.action)) {
      sp_c = s->temp_c;
      p.phase = Phase::hold;
    } else if (const auto* h = std::get_if<HoldStep>(&step.action)) {
      p.duration_s = h->duration_s;
      p.phase = Phase::hold;
    } else if (const auto* r = std::get_if<RampStep>(&step.action)) {
      p.duration_s = std::abs(r->target_c - sp_c) / r->rate_c_per_min * 60.0;
      p.phase = r->target_c > sp_c   ? Phase::heating
                : r->target_c < sp_c ? Phase::cooling
                                     : Phase::hold;
      sp_c = r->target_c;
    } else if (const auto* st = std::get_if<SettleStep>(&step.action)) {
      p.duration_s = st->stable_s;
      p.phase = Phase::settle;
    }
    p.end_setpoint_c = sp_c;
    t_s += p.duration_s;
    out.push_back(p);
  }
  return out;
}

double setpoint_in_step(const Step& step, const PlannedStep& planned, double t_in_step_s) {
  const auto* r = std::get_if<RampStep>(&step.action);
  if (r == nullptr) return planned.end_setpoint_c;
  if (t_in_step_s >= planned.duration_s) return planned.end_setpoint_c;
  const double direction = planned.end_setpoint_c >= planned.start_setpoint_c ? 1.0 : -1.0;
  return planned.start_setpoint_c + direction * r->rate_c_per_min / 60.0 * t_in_step_s;
}

}  // namespace detail

double Profile::nominal_duration_s() const {
  const auto p = detail::plan(*this);
  return p.empty() ? 0.0 : p.back().start_s + p.back().duration_s;
}

std::expected<void, ProfileError> check_rate_limits(const Profile& profile, double max_rate_dps) {
  using detail::format_number;
  ProfileError e;
  e.source = profile.source_name;
  if (!std::isfinite(max_rate_dps) || max_rate_dps <= 0.0) {
    e.message = "the rate table's limit must be a positive max_rate_dps, got " + format_number(max_rate_dps) + " deg/s";
    return std::unexpected(std::move(e));
  }
  for (const auto& r : profile.rate_steps) {
    if (std::fabs(r.rate_dps) > max_rate_dps) {
      e.line = r.line;
      e.column = r.rate_column;
      e.line_text = r.text;
      e.message = "table rate " + format_number(r.rate_dps) + " deg/s is beyond the rate table's limit +-" +
                  format_number(max_rate_dps) + " deg/s";
      return std::unexpected(std::move(e));
    }
  }
  return {};
}

std::expected<void, ProfileError> check_limits(const Profile& profile,
                                               const ChamberLimits& limits) {
  using detail::format_number;
  auto fail = [&](const Step* step, int column, std::string message) {
    ProfileError e;
    e.source = profile.source_name;
    e.message = std::move(message);
    if (step != nullptr) {
      e.line = step->line;
      e.column = column;
      e.line_text = step->text;
    }
    return std::unexpected(std::move(e));
  };
  if (!std::isfinite(limits.min_c) || !std::isfinite(limits.max_c) ||
      limits.min_c > limits.max_c) {
    return fail(nullptr, 0,
                "chamber limits need finite min_c <= max_c, got min_c " +
                    format_number(limits.min_c) + " degC, max_c " + format_number(limits.max_c) +
                    " degC");
  }
  if (!std::isfinite(limits.max_rate_c_per_min) || limits.max_rate_c_per_min <= 0.0) {
    return fail(nullptr, 0,
                "chamber limits need a positive max_rate_c_per_min, got " +
                    format_number(limits.max_rate_c_per_min) + " degC/min");
  }
  // One message shape for setpoints and ramp targets, so that both read the same.
  auto check_temp = [&](const Step& step, const char* what, double temp_c,
                        int column) -> std::expected<void, ProfileError> {
    if (temp_c > limits.max_c) {
      return fail(&step, column,
                  std::string(what) + " " + format_number(temp_c) +
                      " degC is above the chamber's maximum " + format_number(limits.max_c) +
                      " degC");
    }
    if (temp_c < limits.min_c) {
      return fail(&step, column,
                  std::string(what) + " " + format_number(temp_c) +
                      " degC is below the chamber's minimum " + format_number(limits.min_c) +
                      " degC");
    }
    return {};
  };
  for (const Step& step : profile.steps) {
    if (const auto* s = std::get_if<SetpointStep>(&step.action)) {
      if (auto ok = check_temp(step, "setpoint", s->temp_c, s->temp_column); !ok) return ok;
    } else if (const auto* r = std::get_if<RampStep>(&step.action)) {
      if (auto ok = check_temp(step, "ramp target", r->target_c, r->target_column); !ok) {
        return ok;
      }
      if (r->rate_c_per_min > limits.max_rate_c_per_min) {
        return fail(&step, r->rate_column,
                    "ramp rate " + format_number(r->rate_c_per_min) +
                        " degC/min is above the chamber's maximum " +
                        format_number(limits.max_rate_c_per_min) + " degC/min");
      }
    }
  }
  return {};
}

std::vector<NominalPoint> nominal_setpoints(const Profile& profile, double dt_s) {
  std::vector<NominalPoint> out;
  if (!std::isfinite(dt_s) || dt_s <= 0.0 || profile.steps.empty()) return out;
  const auto planned = detail::plan(profile);
  const double total_s = planned.back().start_s + planned.back().duration_s;
  // The relative tolerance keeps a duration that is a whole number of dt_s from gaining a
  // point through rounding (6000 / 60 must give 100 intervals, not 101).
  const auto intervals = static_cast<std::size_t>(std::ceil(total_s / dt_s - 1e-9));
  out.reserve(intervals + 1);
  std::size_t i = 0;
  for (std::size_t k = 0; k <= intervals; ++k) {
    const double t_s = static_cast<double>(k) * dt_s;
    // Advance past finished steps; zero-length ones (setpoints) are passed at once.
    while (i < planned.size() && t_s >= planned[i].start_s + planned[i].duration_s) ++i;
    NominalPoint pt;
    pt.time_s = t_s;
    if (i == planned.size()) {
      pt.setpoint_c = planned.back().end_setpoint_c;
      pt.phase = Phase::hold;
      pt.step_index = planned.size() - 1;
    } else {
      pt.setpoint_c = detail::setpoint_in_step(profile.steps[i], planned[i], t_s - planned[i].start_s);
      pt.phase = planned[i].phase;
      pt.step_index = i;
    }
    out.push_back(pt);
  }
  return out;
}

}  // namespace fogbench::profiles
