// Names of phases and axes, as they appear in CSV files, JSON and reports; picking an axis.
#include "fogbench/model/run.hpp"

namespace fogbench::model {

std::string_view to_string(Phase p) {
  switch (p) {
    case Phase::settle: return "settle";
    case Phase::hold: return "hold";
    case Phase::heating: return "heating";
    case Phase::cooling: return "cooling";
    case Phase::unknown: break;
  }
  return "unknown";
}

std::optional<Phase> phase_from_string(std::string_view s) {
  for (Phase p : {Phase::unknown, Phase::settle, Phase::hold, Phase::heating, Phase::cooling})
    if (to_string(p) == s) return p;
  return std::nullopt;
}

std::string_view to_string(Axis a) {
  switch (a) {
    case Axis::y: return "y";
    case Axis::z: return "z";
    case Axis::x: break;
  }
  return "x";
}

std::optional<Axis> axis_from_string(std::string_view s) {
  for (Axis a : {Axis::x, Axis::y, Axis::z})
    if (to_string(a) == s) return a;
  return std::nullopt;
}

std::expected<RunData, std::string> select_axis(RunData run, Axis axis) {
  const std::string name = run.name.empty() ? "the run" : run.name;
  if (run.axis) {
    if (*run.axis == axis) return run;
    return std::unexpected(name + ": axis " + std::string(to_string(axis)) + ": this run holds axis " +
                           std::string(to_string(*run.axis)) + " alone (picked before)");
  }
  if (!run.has_axes()) {
    if (axis == Axis::x) return run;
    return std::unexpected(name + ": axis " + std::string(to_string(axis)) +
                           ": a one-axis run (no gyro_y_dph, gyro_z_dph columns): its only axis is x");
  }
  if (axis == Axis::y) run.gyro_dph = std::move(run.gyro_y_dph);
  else if (axis == Axis::z) run.gyro_dph = std::move(run.gyro_z_dph);
  if (axis != Axis::x) run.compensated_dph.clear();
  if (run.has_axis_thermistors()) {
    const auto k = static_cast<std::size_t>(axis);
    run.t1_c = run.axis_t1_c[k];
    run.t2_c = run.axis_t2_c[k];
  }
  run.gyro_y_dph.clear();
  run.gyro_z_dph.clear();
  run.axis = axis;
  return run;
}

}  // namespace fogbench::model
