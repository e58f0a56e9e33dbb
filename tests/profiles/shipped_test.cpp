// The shipped profiles: all parse and fit a chamber; the paper's three are exactly the runs
// of METHOD.md; the qualification covers what it claims. Also the nominal timeline.
#include <catch2/catch.hpp>

#include <algorithm>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "fogbench/profiles/profile.hpp"
#include "read_text.hpp"

using namespace fogbench::profiles;

namespace {

Profile load(const std::string& name) {
  const std::string text = read_source_file("profiles/" + name);
  INFO("profiles/" << name);
  REQUIRE_FALSE(text.empty());
  auto p = parse_profile(text, name);
  INFO((p ? std::string() : p.error().to_string()));
  REQUIRE(p.has_value());
  return *p;
}

// The paper's run after the initial settle, as METHOD.md lists it: holds (min) and ramps
// (target degC, rate degC/min), written as {0, minutes} and {target, rate}.
struct Expected {
  StepKind kind;
  double a, b;
};

void check_run(const Profile& p, const std::vector<Expected>& expected) {
  // Opening: setpoint 20 C, then a settle on the coil ("chamber at 20 degC and stable").
  REQUIRE(p.steps.size() == 2 + expected.size());
  REQUIRE(p.steps[0].kind() == StepKind::setpoint);
  CHECK(std::get<SetpointStep>(p.steps[0].action).temp_c == 20.0);
  REQUIRE(p.steps[1].kind() == StepKind::settle);
  CHECK(std::get<SettleStep>(p.steps[1].action).on == SettleOn::coil);
  for (std::size_t i = 0; i < expected.size(); ++i) {
    const Step& s = p.steps[2 + i];
    INFO("line " << s.line << ": " << s.text);
    REQUIRE(s.kind() == expected[i].kind);
    if (expected[i].kind == StepKind::hold) {
      CHECK(std::get<HoldStep>(s.action).duration_s == expected[i].b * 60.0);
    } else {
      CHECK(std::get<RampStep>(s.action).target_c == expected[i].a);
      CHECK(std::get<RampStep>(s.action).rate_c_per_min == expected[i].b);
    }
  }
}

constexpr auto H = StepKind::hold;
constexpr auto R = StepKind::ramp;

}  // namespace

TEST_CASE("exp1.profile is experiment 1 of METHOD.md") {
  // hold 10 min; ramp 1 degC/min to 10; hold 20 min; ramp 1 to 30; hold 20 min; ramp 1 to 20.
  check_run(load("exp1.profile"),
            {{H, 0, 10}, {R, 10, 1}, {H, 0, 20}, {R, 30, 1}, {H, 0, 20}, {R, 20, 1}});
}

TEST_CASE("exp2.profile is experiment 2 of METHOD.md") {
  // hold 10 min; ramp 1 degC/min to 25; hold 20 min; ramp 1 to 15; hold 20 min; ramp 1 to 20.
  check_run(load("exp2.profile"),
            {{H, 0, 10}, {R, 25, 1}, {H, 0, 20}, {R, 15, 1}, {H, 0, 20}, {R, 20, 1}});
}

TEST_CASE("exp3.profile is experiment 3 of METHOD.md") {
  // hold 10 min; ramp 0.5 to 5; hold 20 min; ramp 0.5 to 35; hold 20 min; ramp 1 to 20.
  check_run(load("exp3.profile"),
            {{H, 0, 10}, {R, 5, 0.5}, {H, 0, 20}, {R, 35, 0.5}, {H, 0, 20}, {R, 20, 1}});
}

TEST_CASE("every shipped profile fits a chamber of -40..+70 degC at 2 degC/min") {
  const ChamberLimits tactical{-40.0, 70.0, 2.0};
  for (const char* name : {"exp1.profile", "exp2.profile", "exp3.profile",
                           "qualification.profile"}) {
    const Profile p = load(name);
    const auto r = check_limits(p, tactical);
    INFO(name << ": " << (r ? std::string() : r.error().to_string()));
    CHECK(r.has_value());
  }
  // The paper's runs stay within 5..35 degC at up to 1 degC/min, a far smaller chamber.
  for (const char* name : {"exp1.profile", "exp2.profile", "exp3.profile"}) {
    CHECK(check_limits(load(name), ChamberLimits{5.0, 35.0, 1.0}).has_value());
  }
}

TEST_CASE("qualification.profile covers the range, three rates both ways, and fits a night") {
  const Profile p = load("qualification.profile");
  std::set<std::pair<double, bool>> rates;  // (degC/min, heating)
  double lowest_c = 20.0, highest_c = 20.0;
  double setpoint_c = 0.0;
  for (const Step& s : p.steps) {
    if (const auto* sp = std::get_if<SetpointStep>(&s.action)) setpoint_c = sp->temp_c;
    if (const auto* r = std::get_if<RampStep>(&s.action)) {
      rates.insert({r->rate_c_per_min, r->target_c > setpoint_c});
      setpoint_c = r->target_c;
      lowest_c = std::min(lowest_c, setpoint_c);
      highest_c = std::max(highest_c, setpoint_c);
    }
  }
  CHECK(lowest_c == -40.0);
  CHECK(highest_c == 70.0);
  for (double rate : {0.5, 1.0, 2.0}) {
    INFO(rate << " degC/min");
    CHECK(rates.count({rate, true}) == 1);
    CHECK(rates.count({rate, false}) == 1);
  }
  // Its header claims 8 h 20 min = 30000 s with settles at their minimum: the sum of its
  // steps, listed in docs/profiles.md.
  CHECK(p.nominal_duration_s() == Approx(30000.0));
}

TEST_CASE("nominal_setpoints walks exp1 with every settle met at its 'for' time") {
  const Profile p = load("exp1.profile");
  // settle 600 s, then the run's 5400 s (see the executor test): 6000 s.
  CHECK(p.nominal_duration_s() == 6000.0);
  const auto pts = nominal_setpoints(p, 60.0);
  REQUIRE(pts.size() == 101);  // t = 0, 60, .., 6000
  CHECK(pts[0].time_s == 0.0);
  CHECK(pts[0].phase == Phase::settle);
  CHECK(pts[0].step_index == 1);  // the setpoint step takes no time
  CHECK(pts[0].setpoint_c == 20.0);
  CHECK(pts[10].phase == Phase::hold);  // 600 s: the settle is over, the hold begins
  CHECK(pts[10].step_index == 2);
  // 1500 s is 300 s into the ramp to 10 that starts at 1200 s: 15 degC.
  CHECK(pts[25].phase == Phase::cooling);
  CHECK(pts[25].setpoint_c == Approx(15.0));
  // The ramp to 30 follows the 1200 s hold (1800 .. 3000 s) and runs 3000 .. 4200 s: at its
  // start 10 degC, halfway (3600 s) 20 degC, then the hold at 30 degC from 4200 s.
  CHECK(pts[50].phase == Phase::heating);
  CHECK(pts[50].setpoint_c == 10.0);
  CHECK(pts[60].phase == Phase::heating);
  CHECK(pts[60].setpoint_c == Approx(20.0));
  CHECK(pts[70].phase == Phase::hold);
  CHECK(pts[70].setpoint_c == 30.0);
  CHECK(pts[100].time_s == 6000.0);
  CHECK(pts[100].phase == Phase::hold);
  CHECK(pts[100].setpoint_c == 20.0);

  // A step that does not divide the duration gets one point past the end: ceil(6000 / 7)
  // = 858 intervals, the last at 6006 s.
  const auto odd = nominal_setpoints(p, 7.0);
  REQUIRE(odd.size() == 859);
  CHECK(odd.back().time_s == 6006.0);
  CHECK(nominal_setpoints(p, 0.0).empty());
  CHECK(nominal_setpoints(p, -1.0).empty());
}
