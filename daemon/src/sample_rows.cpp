// One second of a run as stored and as pushed (sample_rows.hpp).
#include "fogbench/daemon/sample_rows.hpp"

#include <cmath>

#include "fogbench/daemon/tick_input.hpp"
#include "fogbench/storage/run_data.hpp"

namespace fogbench::daemon {

namespace {
double or_nan(std::optional<double> v) { return v ? *v : storage::kNoValue; }
std::optional<double> finite(double v) { return std::isfinite(v) ? std::optional(v) : std::nullopt; }
}  // namespace

std::uint8_t quality_flags(const UnitReading& u, const TickInput& in, bool pv_frozen, double table_max_abs_dps) {
  std::uint8_t f = 0;
  if (!u.gyro_dph || !u.t1_c || !u.t2_c || !in.chamber_c) f |= model::flag::missing;
  if (u.frames_lost > 0 || u.frames_corrupt > 0) f |= model::flag::frames_lost;
  // A gyro at its count limit reads a clipped rate: never stored as if it were the rate.
  bool oor = u.out_of_range || u.frames_saturated > 0;
  for (auto t : {u.t1_c, u.t2_c})
    if (t && (*t < kCoilMinC || *t > kCoilMaxC)) oor = true;
  // Per-axis thermistors count as the unit's: one not read is a missing second.
  for (const auto* axis : {&u.axis_t1_c, &u.axis_t2_c})
    for (const auto& t : *axis) {
      if (!t) f |= model::flag::missing;
      else if (*t < kCoilMinC || *t > kCoilMaxC) oor = true;
    }
  if (u.gyro_dph && std::abs(*u.gyro_dph) > kGyroMaxAbsDph + 3600.0 * std::abs(table_max_abs_dps)) oor = true;
  // A three-axis unit's y and z count as its gyro: an axis without a usable frame is a missing
  // second, its lost frames are the second's.
  for (const AxisReading& a : u.extra_axes) {
    if (!a.rate_dph) f |= model::flag::missing;
    if (a.frames_lost > 0 || a.frames_corrupt > 0) f |= model::flag::frames_lost;
    if ((a.rate_dph && std::abs(*a.rate_dph) > kGyroMaxAbsDph) || a.frames_saturated > 0) oor = true;
  }
  if (oor) f |= model::flag::out_of_range;
  if (in.chamber_link_down) f |= model::flag::link_gap;
  if (pv_frozen) f |= model::flag::pv_frozen;
  return f;
}

storage::SampleRow sample_row(int unit_index, const UnitReading& u, const TickInput& in, double t_s,
                              const profiles::ExecutorStatus& st, bool pv_frozen,
                              std::optional<double> since_power_on_s, double table_max_abs_dps) {
  storage::SampleRow r;
  r.unit_index = unit_index;
  r.t_s = t_s;
  r.wall_time = in.wall_time;
  r.setpoint_c = st.setpoint_c;
  r.chamber_c = or_nan(in.chamber_c);
  r.gyro_dph = or_nan(u.gyro_dph);
  if (u.extra_axes.size() >= 1) r.gyro_y_dph = or_nan(u.extra_axes[0].rate_dph);
  if (u.extra_axes.size() >= 2) r.gyro_z_dph = or_nan(u.extra_axes[1].rate_dph);
  r.frames = u.frames;
  r.t1_c = or_nan(u.t1_c);
  r.t2_c = or_nan(u.t2_c);
  if (u.axis_t1_c.size() == 2 && u.axis_t2_c.size() == 2) {
    r.t1_y_c = or_nan(u.axis_t1_c[0]);
    r.t2_y_c = or_nan(u.axis_t2_c[0]);
    r.t1_z_c = or_nan(u.axis_t1_c[1]);
    r.t2_z_c = or_nan(u.axis_t2_c[1]);
  }
  r.phase = storage::model_phase(st.phase);
  r.step = static_cast<int>(st.step_index);
  r.flags = quality_flags(u, in, pv_frozen, table_max_abs_dps);
  r.since_power_on_s = or_nan(since_power_on_s);
  return r;
}

protocol::SampleMessage sample_message(const storage::SampleRow& r, std::int64_t run_id, const std::string& serial,
                                       storage::RunState state, const profiles::ExecutorStatus& st,
                                       std::optional<double> chamber_c, int axes) {
  protocol::SampleMessage m;
  m.run_id = run_id;
  m.t_s = r.t_s;
  m.state = std::string(storage::to_string(state));
  m.phase = std::string(profiles::to_string(st.phase));
  m.step = st.step_index;
  m.elapsed_s = r.t_s;
  m.remaining_s = st.remaining_s;
  m.setpoint_c = st.setpoint_c;
  m.chamber_c = chamber_c;
  m.unit = r.unit_index;
  m.serial = serial;
  m.gyro_dph = finite(r.gyro_dph);
  m.frames = r.frames.value_or(0);
  m.t1_c = finite(r.t1_c);
  m.t2_c = finite(r.t2_c);
  m.flags = r.flags;
  m.since_power_on_s = finite(r.since_power_on_s);
  m.compensated_dph = finite(r.compensated_dph);
  m.rate_in_dps = finite(r.rate_in_dps);  // NaN (none) unless the run drives a rate table
  m.three_axis = axes == 3;
  if (m.three_axis) {
    m.gyro_y_dph = finite(r.gyro_y_dph);
    m.gyro_z_dph = finite(r.gyro_z_dph);
    // Per-axis thermistors where the unit has them: a second with any of them.
    m.axis_thermistors = std::isfinite(r.t1_y_c) || std::isfinite(r.t2_y_c) || std::isfinite(r.t1_z_c) || std::isfinite(r.t2_z_c);
    if (m.axis_thermistors) {
      m.t1_y_c = finite(r.t1_y_c);
      m.t2_y_c = finite(r.t2_y_c);
      m.t1_z_c = finite(r.t1_z_c);
      m.t2_z_c = finite(r.t2_z_c);
    }
  }
  return m;
}

}  // namespace fogbench::daemon
