// RateSchedule: the rate table's command over a run, from the rate steps of each plateau (issue 29,
// point 1). No clock: the temperature executor is stepped with given times.
#include <catch2/catch.hpp>

#include <cmath>
#include <string>
#include <vector>

#include "fogbench/profiles/executor.hpp"
#include "fogbench/profiles/rate_schedule.hpp"
#include "parse_helpers.hpp"

using namespace fogbench::profiles;
using fogbench::profiles::test::parse_ok;

namespace {

// The commanded rate at each whole second 0..n-1 of a run whose settles are met at once.
std::vector<double> rates_per_second(const Profile& p, int n) {
  Executor ex(p);
  RateSchedule rs(p);
  Readings r;
  std::vector<double> out;
  for (int k = 0; k < n; ++k) {
    r.chamber_c = ex.update(k, r).setpoint_c;  // the chamber follows at once
    out.push_back(rs.at(ex.update(k, r)).rate_dps);
  }
  return out;
}

}  // namespace

TEST_CASE("rate schedule: a hold's sequence from its start, steps in order, rest after it") {
  const auto p = parse_ok(
      "setpoint 20 C\n"
      "hold 10 s\n"
      "rate 5 dps for 3 s\n"
      "rate -5 dps for 4 s\n");
  const std::vector<double> want = {5, 5, 5, -5, -5, -5, -5, 0, 0, 0, 0, 0};
  CHECK(rates_per_second(p, 12) == want);
}

TEST_CASE("rate schedule: each plateau its own sequence, 0 during ramps and settles") {
  const auto p = parse_ok(
      "setpoint 20 C\n"
      "hold 4 s\n"
      "rate 10 dps for 2 s\n"
      "ramp to 21 C at 30 C/min\n"  // 2 s
      "settle within 0.5 C for 2 s\n"
      "hold 3 s\n"
      "rate -20 dps for 1 s\n"
      "rate 30 dps for 1 s\n");
  const RateSchedule rs(p);
  CHECK_FALSE(rs.empty());
  CHECK(rs.max_abs_rate_dps() == 30.0);  // the largest |rate| of every plateau's sequence
  CHECK(RateSchedule(parse_ok("setpoint 20 C\nhold 5 s\nrate -45 dps for 5 s\n")).max_abs_rate_dps() == 45.0);
  CHECK(rs.at(1, 0.0).rate_dps == 10.0);
  CHECK(rs.at(1, 0.0).rate_step == 0u);
  CHECK(rs.at(1, 1.999).rate_dps == 10.0);
  CHECK(rs.at(1, 2.0).rate_dps == 0.0);  // the step's end belongs to what follows
  CHECK_FALSE(rs.at(1, 2.0).rate_step.has_value());
  CHECK(rs.at(2, 0.5).rate_dps == 0.0);  // the ramp
  CHECK(rs.at(3, 0.5).rate_dps == 0.0);  // the settle
  CHECK(rs.at(4, 0.0).rate_dps == -20.0);
  CHECK(rs.at(4, 1.0).rate_dps == 30.0);
  CHECK(rs.at(4, 1.0).rate_step == 2u);
  CHECK(rs.at(4, 2.0).rate_dps == 0.0);
  CHECK(rs.at(4, -1.0).rate_dps == 0.0);
  CHECK(rs.at(4, std::nan("")).rate_dps == 0.0);
  // Through the executor: the second plateau's sequence starts when its hold does, however long
  // the settle took (here at its `for` time).
  const std::vector<double> got = rates_per_second(p, 14);
  const std::vector<double> want = {10, 10, 0, 0, 0, 0, 0, 0, -20, 30, 0, 0, 0, 0};
  CHECK(got == want);
}

TEST_CASE("rate schedule: none without rate steps, and 0 once the profile has finished or failed") {
  const auto plain = parse_ok("setpoint 20 C\nhold 5 s\n");
  CHECK(RateSchedule(plain).empty());
  CHECK(RateSchedule(plain).max_abs_rate_dps() == 0.0);
  CHECK(RateSchedule(plain).at(1, 1.0).rate_dps == 0.0);
  const auto p = parse_ok("setpoint 20 C\nhold 5 s\nrate 7 dps for 5 s\n");
  const RateSchedule rs(p);
  ExecutorStatus s;
  s.step_index = 1;
  s.step_elapsed_s = 1.0;
  CHECK(rs.at(s).rate_dps == 7.0);
  s.finished = true;
  CHECK(rs.at(s).rate_dps == 0.0);
  s.finished = false;
  s.failed = true;
  CHECK(rs.at(s).rate_dps == 0.0);
}
