// One second's rows and messages, built without a store or a clock (sample_rows.hpp).
#include <catch2/catch.hpp>

#include <cmath>

#include "fogbench/daemon/sample_rows.hpp"
#include "fogbench/daemon/station.hpp"

using namespace fogbench;
using namespace fogbench::daemon;

namespace {
UnitReading good_unit() {
  UnitReading u;
  u.gyro_dph = -8.0;
  u.frames = 100;
  u.t1_c = 20.0;
  u.t2_c = 20.5;
  return u;
}
TickInput good_input() {
  TickInput in;
  in.wall_time = 1795298101.0;
  in.chamber_c = 20.1;
  in.chamber_setpoint_c = 20.0;
  return in;
}
}  // namespace

TEST_CASE("sample rows: a second read in full has no flags") {
  CHECK(quality_flags(good_unit(), good_input(), false) == 0);
}

TEST_CASE("sample rows: each fault sets its own flag") {
  UnitReading u = good_unit();
  u.t2_c.reset();
  CHECK(quality_flags(u, good_input(), false) == model::flag::missing);
  TickInput no_air = good_input();
  no_air.chamber_c.reset();
  CHECK(quality_flags(good_unit(), no_air, false) == model::flag::missing);
  u = good_unit();
  u.frames_corrupt = 1;
  CHECK(quality_flags(u, good_input(), false) == model::flag::frames_lost);
  u = good_unit();
  u.t1_c = kCoilMaxC + 1.0;
  CHECK(quality_flags(u, good_input(), false) == model::flag::out_of_range);
  u = good_unit();
  u.gyro_dph = -2.0 * kGyroMaxAbsDph;
  CHECK(quality_flags(u, good_input(), false) == model::flag::out_of_range);
  // On a rate table spinning up to 100 deg/s (3.6e5 deg/h) the same reading is the table's rate
  // plus a drift: plausible; beyond the table's largest rate plus the drift bound it is not.
  CHECK(quality_flags(u, good_input(), false, 100.0) == 0);
  CHECK(quality_flags(u, good_input(), false, -100.0) == 0);
  u.gyro_dph = 100.0 * 3600.0 + 1.5 * kGyroMaxAbsDph;
  CHECK(quality_flags(u, good_input(), false, 100.0) == model::flag::out_of_range);
  TickInput gap = good_input();
  gap.chamber_link_down = true;
  CHECK(quality_flags(good_unit(), gap, false) == model::flag::link_gap);
  CHECK(quality_flags(good_unit(), good_input(), true) == model::flag::pv_frozen);
}

TEST_CASE("sample rows: the row records the profile's setpoint and phase, values not read as NaN") {
  profiles::ExecutorStatus st;
  st.setpoint_c = 21.5;
  st.phase = profiles::Phase::heating;
  st.step_index = 2;
  st.remaining_s = 100.0;
  UnitReading u = good_unit();
  u.t1_c.reset();
  const auto r = sample_row(1, u, good_input(), 42.0, st, false, std::nullopt);
  CHECK(r.unit_index == 1);
  CHECK(r.t_s == 42.0);
  CHECK(r.setpoint_c == 21.5);  // the profile's, not the controller's read-back (20.0)
  CHECK(r.phase == model::Phase::heating);
  CHECK(r.step == 2);
  CHECK(std::isnan(r.t1_c));
  CHECK(std::isnan(r.since_power_on_s));
  CHECK(r.flags == model::flag::missing);

  const auto m = sample_message(r, 7, "FOG-0002", storage::RunState::running, st, good_input().chamber_c);
  CHECK(m.run_id == 7);
  CHECK(m.serial == "FOG-0002");
  CHECK(m.state == "running");
  CHECK(m.phase == "heating");
  CHECK_FALSE(m.t1_c.has_value());  // null on the wire
  CHECK(m.gyro_dph == -8.0);
  CHECK(m.remaining_s == 100.0);
}

TEST_CASE("sample rows: a three-axis unit's per-axis thermistors are stored and sent, one not read flags the second") {
  profiles::ExecutorStatus st;
  UnitReading u = good_unit();
  u.extra_axes.resize(2);
  u.extra_axes[0].rate_dph = 1.0;
  u.extra_axes[1].rate_dph = 2.0;
  u.axis_t1_c = {24.0, 23.0};  // y, z
  u.axis_t2_c = {24.5, 23.5};
  CHECK(quality_flags(u, good_input(), false) == 0);
  auto r = sample_row(0, u, good_input(), 10.0, st, false, std::nullopt);
  CHECK(r.t1_y_c == 24.0);
  CHECK(r.t2_y_c == 24.5);
  CHECK(r.t1_z_c == 23.0);
  CHECK(r.t2_z_c == 23.5);
  auto m = sample_message(r, 1, "FOG-3AX", storage::RunState::running, st, good_input().chamber_c, 3);
  CHECK(m.axis_thermistors);
  CHECK(m.t1_z_c == 23.0);

  u.axis_t2_c[1].reset();  // z's outer wall not read
  CHECK(quality_flags(u, good_input(), false) == model::flag::missing);
  r = sample_row(0, u, good_input(), 11.0, st, false, std::nullopt);
  CHECK(std::isnan(r.t2_z_c));
  m = sample_message(r, 1, "FOG-3AX", storage::RunState::running, st, good_input().chamber_c, 3);
  CHECK(m.axis_thermistors);
  CHECK_FALSE(m.t2_z_c.has_value());
  u.axis_t2_c[1] = kCoilMaxC + 1.0;
  CHECK(quality_flags(u, good_input(), false) == model::flag::out_of_range);

  // A unit whose axes share its thermistors: no such columns, no such fields.
  UnitReading shared = good_unit();
  shared.extra_axes = u.extra_axes;
  r = sample_row(0, shared, good_input(), 12.0, st, false, std::nullopt);
  CHECK(std::isnan(r.t1_y_c));
  CHECK_FALSE(sample_message(r, 1, "FOG-3AX", storage::RunState::running, st, good_input().chamber_c, 3).axis_thermistors);
}
