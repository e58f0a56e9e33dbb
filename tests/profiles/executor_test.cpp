// The executor, fed times and readings: the setpoints through a whole paper profile, exact
// step hand-over between irregular calls, and the settle rule (overshoot, coil, slope,
// missing readings, timeout).
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "fogbench/profiles/executor.hpp"
#include "read_text.hpp"

using namespace fogbench::profiles;

namespace {

Profile parse_ok(std::string_view text, std::string_view name = "ex.profile") {
  auto p = parse_profile(text, name);
  INFO((p ? std::string() : p.error().to_string()));
  REQUIRE(p.has_value());
  return *p;
}

// Feeds one update a second for t = 0 .. last_s and keeps every status, indexed by t.
template <class ReadingsAt>
std::vector<ExecutorStatus> run(const Profile& profile, int last_s, ReadingsAt readings_at) {
  Executor ex(profile);
  std::vector<ExecutorStatus> out;
  for (int t = 0; t <= last_s; ++t) out.push_back(ex.update(t, readings_at(t)));
  return out;
}

Readings chamber_at(double c) { return Readings{c, {}}; }

}  // namespace

TEST_CASE("exp1 through a perfect chamber: setpoints, phases, steps and the finish time") {
  const std::string text = read_source_file("profiles/exp1.profile");
  REQUIRE_FALSE(text.empty());
  const Profile p = parse_ok(text, "exp1.profile");
  // The derivations below rest on this shape (the shipped-profile test checks its values):
  // 0 setpoint 20, 1 settle on coil with a slope for 10 min, 2 hold 10 min, 3 ramp to 10,
  // 4 hold 20 min, 5 ramp to 30, 6 hold 20 min, 7 ramp to 20, all at 1 degC/min.
  REQUIRE(p.steps.size() == 8);

  // A chamber whose air and coil (one unit) follow the commanded setpoint exactly.
  Executor ex(p);
  std::vector<ExecutorStatus> s;
  double commanded_c = 20.0;
  for (int t = 0; t <= 6100; ++t) {
    s.push_back(ex.update(t, Readings{commanded_c, {{commanded_c, commanded_c}}}));
    commanded_c = s.back().setpoint_c;
  }

  // The settle's slope is judged once the readings span 30 s, at t = 30; the coil then sits
  // on the setpoint with zero slope, so it is met 600 s later: the settle ends at 630 s.
  CHECK(s[0].phase == Phase::settle);
  CHECK(s[0].step_index == 1);
  CHECK(s[0].setpoint_c == 20.0);
  CHECK(s[0].remaining_s == 6000.0);  // settle 600 + 10 + 10 + 20 + 20 + 20 + 10 min = 6000 s
  CHECK(s[629].phase == Phase::settle);
  // hold 10 min: 630 .. 1230 s.
  CHECK(s[630].phase == Phase::hold);
  CHECK(s[630].step_index == 2);
  CHECK(s[630].step_elapsed_s == 0.0);
  CHECK(s[630].remaining_s == 5400.0);
  // ramp to 10 at 1 degC/min: 10 degC take 600 s, 1230 .. 1830 s.
  CHECK(s[1230].phase == Phase::cooling);
  CHECK(s[1230].setpoint_c == 20.0);
  // 300 s in: 20 - 1 * 300 / 60 = 15 degC; left: 300 s of ramp + 1200 + 1200 + 1200 + 600.
  CHECK(s[1530].setpoint_c == Approx(15.0).margin(1e-9));
  CHECK(s[1530].step_elapsed_s == 300.0);
  CHECK(s[1530].remaining_s == Approx(4500.0));
  CHECK(s[1530].step_line == p.steps[3].line);
  CHECK(p.steps[3].text.starts_with("ramp to 10 C"));
  // hold 20 min at 10 degC: 1830 .. 3030 s.
  CHECK(s[1830].phase == Phase::hold);
  CHECK(s[1830].step_index == 4);
  CHECK(s[1830].setpoint_c == 10.0);
  // ramp to 30: 20 degC take 1200 s, 3030 .. 4230 s; halfway (600 s) it is at 20 degC.
  CHECK(s[3030].phase == Phase::heating);
  CHECK(s[3630].setpoint_c == Approx(20.0).margin(1e-9));
  // hold 20 min at 30 degC: 4230 .. 5430 s.
  CHECK(s[4230].phase == Phase::hold);
  CHECK(s[4230].setpoint_c == 30.0);
  // ramp to 20: 600 s, 5430 .. 6030 s; 300 s in: 30 - 5 = 25 degC.
  CHECK(s[5430].phase == Phase::cooling);
  CHECK(s[5730].setpoint_c == Approx(25.0).margin(1e-9));
  CHECK_FALSE(s[6029].finished);
  CHECK(s[6029].setpoint_c == Approx(30.0 - 599.0 / 60.0).margin(1e-9));
  // Finished at 6030 s, holding the final 20 degC.
  CHECK(s[6030].finished);
  CHECK(s[6030].phase == Phase::hold);
  CHECK(s[6030].setpoint_c == 20.0);
  CHECK(s[6030].remaining_s == 0.0);
  CHECK(s[6030].step_index == 7);
  CHECK(s[6100].finished);
  CHECK_FALSE(s[6100].failed);

  // After the 30 s the slope took, the run is the nominal timeline shifted by 30 s.
  const auto nominal = nominal_setpoints(p, 1.0);
  for (int t = 30; t <= 6030; ++t) {
    const auto& n = nominal[static_cast<std::size_t>(t - 30)];
    INFO("t = " << t);
    REQUIRE(s[t].setpoint_c == Approx(n.setpoint_c).margin(1e-9));
    REQUIRE(s[t].phase == n.phase);
    REQUIRE(s[t].step_index == n.step_index);
  }
}

TEST_CASE("steps hand over at their exact end time, whatever the call times") {
  const Profile p = parse_ok("setpoint 20 C\nhold 10 s\nramp to 30 C at 1 C/min\nhold 1 min\n");
  Executor ex(p);
  CHECK(ex.update(0.0, chamber_at(20)).phase == Phase::hold);
  // The hold ended at 10 s, so at 40 s the ramp is 30 s old: 20 + 30 / 60 = 20.5 degC.
  const auto a = ex.update(40.0, chamber_at(20));
  CHECK(a.step_index == 2);
  CHECK(a.step_elapsed_s == 30.0);
  CHECK(a.setpoint_c == Approx(20.5));
  // An irregular call: 40.7 s is 30.7 s into the ramp.
  CHECK(ex.update(40.7, chamber_at(20)).setpoint_c == Approx(20.0 + 30.7 / 60.0));
  // A gap over the ramp's end (10 + 600 = 610 s) and the hold's (670 s): finished, and the
  // last step began at 610 s.
  const auto b = ex.update(700.0, chamber_at(20));
  CHECK(b.finished);
  CHECK(b.setpoint_c == 30.0);
  CHECK(b.step_index == 3);
  CHECK(b.step_elapsed_s == 90.0);
}

TEST_CASE("an overshoot restarts the settle timer") {
  const Profile p = parse_ok("setpoint 20 C\nsettle within 0.2 C for 5 min\nhold 1 min\n");
  SECTION("without an overshoot the settle ends after its 300 s") {
    // No slope clause, so the first reading already counts: stable from 0, met at 300.
    const auto s = run(p, 400, [](int) { return chamber_at(20.05); });
    CHECK(s[299].phase == Phase::settle);
    // 200 s into a stable soak: 100 s of it left, then the 60 s hold.
    CHECK(s[200].remaining_s == 160.0);
    CHECK(s[300].phase == Phase::hold);
    CHECK(s[300].step_index == 2);
  }
  SECTION("an overshoot at 100 s pushes the end to 101 + 300 = 401 s") {
    const auto s = run(p, 500, [](int t) { return chamber_at(t == 100 ? 20.5 : 20.1); });
    CHECK(s[100].remaining_s == 360.0);  // the whole 300 s again, then the hold
    CHECK(s[300].phase == Phase::settle);  // where the soak would have ended
    CHECK(s[400].phase == Phase::settle);
    CHECK(s[401].phase == Phase::hold);
    CHECK(s[401].step_elapsed_s == 0.0);
  }
  SECTION("a missing reading is no proof of stability: it restarts the timer too") {
    const double missing = std::numeric_limits<double>::quiet_NaN();
    const auto s = run(p, 500, [&](int t) { return chamber_at(t == 100 ? missing : 20.0); });
    CHECK(s[400].phase == Phase::settle);
    CHECK(s[401].phase == Phase::hold);
  }
}

TEST_CASE("a coil settle waits for every unit's coil, not for the air") {
  // The air is at 20 degC from the start. Unit A's coil approaches from below, unit B's
  // centre from above (a unit that was warmer):
  //   A: t1 = 20 - 5 exp(-t/600) in band once 5 exp(-t/600) <= 0.2, t >= 600 ln 25 = 1931.3 s
  //      t2 = 20 - 2 exp(-t/300) in band from t >= 300 ln 10 = 690.8 s
  //   B: t1 = 20 + 4 exp(-t/800) in band from t >= 800 ln 20 = 2396.6 s;  t2 = 20
  auto unit_a = [](int t) {
    return CoilTemps{20.0 - 5.0 * std::exp(-t / 600.0), 20.0 - 2.0 * std::exp(-t / 300.0)};
  };
  auto unit_b = [](int t) { return CoilTemps{20.0 + 4.0 * std::exp(-t / 800.0), 20.0}; };

  SECTION("on chamber: the air is stable at once, met at 300 s") {
    const Profile p = parse_ok("setpoint 20 C\nsettle within 0.2 C for 5 min\nhold 1 min\n");
    const auto s = run(p, 400, [&](int t) { return Readings{20.0, {unit_a(t), unit_b(t)}}; });
    CHECK(s[300].phase == Phase::hold);
  }
  const Profile p =
      parse_ok("setpoint 20 C\nsettle within 0.2 C on coil for 5 min\nhold 1 min\n");
  SECTION("on coil, one unit: A's centre is last in, at 1932 s; met at 2232 s") {
    const auto s = run(p, 2300, [&](int t) { return Readings{20.0, {unit_a(t)}}; });
    CHECK(s[2231].phase == Phase::settle);
    CHECK(s[2232].phase == Phase::hold);
  }
  SECTION("on coil, two units: B's centre is last in, at 2397 s; met at 2697 s") {
    const auto s = run(p, 2800, [&](int t) { return Readings{20.0, {unit_a(t), unit_b(t)}}; });
    CHECK(s[2696].phase == Phase::settle);
    CHECK(s[2697].phase == Phase::hold);
  }
}

TEST_CASE("a slope limit keeps a settle waiting while the reading still drifts") {
  // The coil centre creeps up at 0.03 degC/min, inside the 1 degC band all along
  // (19.2 -> 19.8 degC), and stops at 1200 s. The least-squares slope over the last 60 s is
  // 0.03 degC/min until the stop, and exactly 0 once the window is all flat (t >= 1260 s),
  // so the 0.02 degC/min limit is first met in (1200, 1260] and the 300 s soak ends in
  // (1500, 1560].
  const Profile p = parse_ok(
      "setpoint 20 C\nsettle within 1 C on coil slope 0.02 C/min for 5 min\nhold 1 min\n");
  auto coil = [](int t) {
    return Readings{20.0, {{19.2 + 0.03 / 60.0 * std::min(t, 1200), 20.0}}};
  };
  const auto s = run(p, 1600, coil);
  CHECK(s[1500].phase == Phase::settle);
  CHECK(s[1560].phase == Phase::hold);
}

TEST_CASE("a settle that is not met by its timeout fails with a reason") {
  SECTION("the air never reaches the band") {
    const Profile p = parse_ok(
        "setpoint 20 C\nsettle within 0.2 C for 5 min timeout 10 min\nhold 1 min\n");
    const auto s = run(p, 700, [](int) { return chamber_at(21.0); });
    CHECK_FALSE(s[599].failed);
    CHECK(s[600].failed);
    CHECK_FALSE(s[600].finished);
    CHECK(s[600].failure_reason ==
          "settle on line 2 timed out after 600 s: chamber 21.000 degC is 1.000 degC from the "
          "setpoint 20 degC (band 0.2 degC)");
    // It stays failed, still on the settle, still commanding its setpoint.
    CHECK(s[700].failed);
    CHECK(s[700].phase == Phase::settle);
    CHECK(s[700].setpoint_c == 20.0);
    CHECK(s[700].step_line == 2);
  }
  SECTION("in band, but not for long enough: in band from 400 s, 200 s by the 600 s timeout") {
    const Profile p = parse_ok(
        "setpoint 20 C\nsettle within 0.2 C for 5 min timeout 10 min\nhold 1 min\n");
    const auto s = run(p, 600, [](int t) { return chamber_at(t < 400 ? 21.0 : 20.0); });
    CHECK(s[600].failed);
    CHECK(s[600].failure_reason ==
          "settle on line 2 timed out after 600 s: met for only 200.0 s of the 300 s it needs");
  }
  SECTION("on coil with no units: the default 2 h timeout, and why") {
    const Profile p =
        parse_ok("setpoint 20 C\nsettle within 0.2 C on coil for 5 min\nhold 1 min\n");
    const auto s = run(p, 7200, [](int) { return chamber_at(20.0); });
    CHECK_FALSE(s[7199].failed);
    CHECK(s[7200].failed);
    CHECK_THAT(s[7200].failure_reason, Catch::EndsWith(": no coil readings"));
  }
  SECTION("a drifting coil names the channel and its slope") {
    const Profile p = parse_ok(
        "setpoint 20 C\nsettle within 1 C on coil slope 0.02 C/min for 5 min timeout 10 min\n");
    // Unit 0 is steady; unit 1's outer wall drifts at 0.06 degC/min, well over the limit.
    const auto s = run(p, 600, [](int t) {
      return Readings{20.0, {{20.0, 20.0}, {20.0, 19.5 + 0.001 * t}}};
    });
    CHECK(s[600].failed);
    CHECK_THAT(s[600].failure_reason,
               Catch::EndsWith("unit 1 coil outer wall (T2) slope 0.0600 degC/min is not "
                               "under 0.02 degC/min"));
  }
}
