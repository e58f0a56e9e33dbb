// check_limits: a profile the chamber cannot do is refused with the line, the value and the
// limit; the bounds are inclusive; nonsensical limits are refused themselves.
#include <catch2/catch.hpp>

#include "fogbench/profiles/profile.hpp"

using namespace fogbench::profiles;

namespace {

Profile parse_ok(std::string_view text) {
  auto p = parse_profile(text, "lim.profile");
  INFO((p ? std::string() : p.error().to_string()));
  REQUIRE(p.has_value());
  return *p;
}

// A small chamber: -40..+70 degC at up to 3 degC/min.
constexpr ChamberLimits chamber{-40.0, 70.0, 3.0};

}  // namespace

TEST_CASE("a ramp target above the maximum is refused at its line and column") {
  const auto p = parse_ok("setpoint 20 C\nramp to 10 C at 1 C/min\nramp to 80 C at 1 C/min\n");
  const auto r = check_limits(p, chamber);
  REQUIRE_FALSE(r.has_value());
  CHECK(r.error().line == 3);
  CHECK(r.error().column == 9);  // "ramp to " is 8 characters
  CHECK(r.error().line_text == "ramp to 80 C at 1 C/min");
  CHECK(r.error().to_string() ==
        "lim.profile:3:9: ramp target 80 degC is above the chamber's maximum 70 degC");
}

TEST_CASE("a setpoint below the minimum is refused") {
  const auto p = parse_ok("setpoint 20 C\nhold 1 min\nsetpoint -55.5 C\n");
  const auto r = check_limits(p, chamber);
  REQUIRE_FALSE(r.has_value());
  CHECK(r.error().line == 3);
  CHECK(r.error().column == 10);
  CHECK(r.error().message == "setpoint -55.5 degC is below the chamber's minimum -40 degC");
}

TEST_CASE("a ramp rate over the maximum is refused, whatever its unit") {
  SECTION("C/min") {
    const auto p = parse_ok("setpoint 20 C\nramp to 30 C at 5 C/min\n");
    const auto r = check_limits(p, chamber);
    REQUIRE_FALSE(r.has_value());
    CHECK(r.error().line == 2);
    CHECK(r.error().column == 17);  // "ramp to 30 C at " is 16 characters
    CHECK(r.error().message == "ramp rate 5 degC/min is above the chamber's maximum 3 degC/min");
  }
  SECTION("C/h: 240 C/h is 4 degC/min") {
    const auto p = parse_ok("setpoint 20 C\nramp to 30 C at 240 C/h\n");
    const auto r = check_limits(p, chamber);
    REQUIRE_FALSE(r.has_value());
    CHECK(r.error().message == "ramp rate 4 degC/min is above the chamber's maximum 3 degC/min");
  }
}

TEST_CASE("limits are inclusive") {
  // Exactly at every limit: a setpoint at the minimum, a target at the maximum, the rate at
  // the maximum (180 C/h = 3 degC/min exactly).
  const auto p = parse_ok(
      "setpoint -40 C\n"
      "ramp to 70 C at 3 C/min\n"
      "ramp to 0 C at 180 C/h\n");
  CHECK(check_limits(p, chamber).has_value());
  // Just outside the maximum, to show the check is live at the edge.
  const auto over = parse_ok("setpoint -40 C\nramp to 70.01 C at 3 C/min\n");
  CHECK_FALSE(check_limits(over, chamber).has_value());
}

TEST_CASE("settle bands and holds are not temperatures the chamber must reach") {
  // A 100 degC band is a tolerance, not a setpoint: no limit applies to it.
  const auto p = parse_ok("setpoint 20 C\nsettle within 100 C for 1 min\nhold 99 h\n");
  CHECK(check_limits(p, chamber).has_value());
}

TEST_CASE("nonsensical limits are refused, not half-applied") {
  const auto p = parse_ok("setpoint 20 C\n");
  SECTION("min above max") {
    const auto r = check_limits(p, ChamberLimits{70.0, -40.0, 3.0});
    REQUIRE_FALSE(r.has_value());
    CHECK(r.error().line == 0);
    CHECK(r.error().to_string() ==
          "lim.profile: chamber limits need finite min_c <= max_c, got min_c 70 degC, max_c "
          "-40 degC");
    CHECK(r.error().excerpt().empty());
  }
  SECTION("zero rate") {
    const auto r = check_limits(p, ChamberLimits{-40.0, 70.0, 0.0});
    REQUIRE_FALSE(r.has_value());
    CHECK(r.error().line == 0);
  }
}
