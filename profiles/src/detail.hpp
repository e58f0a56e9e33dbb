// Internal to fogbench::profiles: the nominal plan that the executor, nominal_setpoints and
// nominal_duration_s share, and number formatting for messages.
#pragma once

#include <string>
#include <vector>

#include "fogbench/profiles/profile.hpp"

namespace fogbench::profiles::detail {

// One step of the nominal timeline (every settle met at its `for` time).
struct PlannedStep {
  double start_s = 0.0;
  double duration_s = 0.0;        // 0 for setpoint steps
  double start_setpoint_c = 0.0;  // the setpoint when the step begins
  double end_setpoint_c = 0.0;    // and when it ends
  Phase phase = Phase::hold;
};

std::vector<PlannedStep> plan(const Profile& profile);

// The setpoint t_in_step_s after a step began, degC; ramps are clamped at their target.
double setpoint_in_step(const Step& step, const PlannedStep& planned, double t_in_step_s);

// The shortest text that reads back as v ("10", "0.5", "-40"): profile values as written.
std::string format_number(double v);
// v with a fixed number of decimals: readings in failure reasons.
std::string format_fixed(double v, int decimals);

}  // namespace fogbench::profiles::detail
