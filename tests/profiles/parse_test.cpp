// The profile text format: every statement and its units, comments and layout, and every
// kind of error with the line and column it must point at.
#include <catch2/catch.hpp>

#include <string>
#include <variant>

#include "fogbench/profiles/profile.hpp"
#include "parse_helpers.hpp"

using namespace fogbench::profiles;

using fogbench::profiles::test::parse_err;
using fogbench::profiles::test::parse_ok;

TEST_CASE("setpoint takes a temperature in C or degC, with decimals and a minus") {
  const auto p = parse_ok("setpoint 20 C\nsetpoint -12.5 degC\nsetpoint 7C\n");
  REQUIRE(p.steps.size() == 3);
  REQUIRE(p.steps[0].kind() == StepKind::setpoint);
  CHECK(std::get<SetpointStep>(p.steps[0].action).temp_c == 20.0);
  // "setpoint " is 9 characters, so the number starts in column 10.
  CHECK(std::get<SetpointStep>(p.steps[0].action).temp_column == 10);
  CHECK(std::get<SetpointStep>(p.steps[1].action).temp_c == -12.5);
  // A unit glued to its number reads as if spaced.
  CHECK(std::get<SetpointStep>(p.steps[2].action).temp_c == 7.0);
  CHECK(p.steps[1].line == 2);
  CHECK(p.steps[1].text == "setpoint -12.5 degC");
}

TEST_CASE("hold converts s, min and h to seconds") {
  const auto p = parse_ok("setpoint 20 C\nhold 30 s\nhold 10 min\nhold 1.5 h\n");
  REQUIRE(p.steps.size() == 4);
  CHECK(p.steps[1].kind() == StepKind::hold);
  CHECK(std::get<HoldStep>(p.steps[1].action).duration_s == 30.0);
  CHECK(std::get<HoldStep>(p.steps[2].action).duration_s == 600.0);   // 10 * 60
  CHECK(std::get<HoldStep>(p.steps[3].action).duration_s == 5400.0);  // 1.5 * 3600
}

TEST_CASE("ramp takes a target and a rate in C/min or C/h") {
  const auto p = parse_ok(
      "setpoint 20 C\n"
      "ramp to 10 C at 1 C/min\n"
      "ramp to 30 degC at 30 C/h\n"
      "ramp to -5 C at 2 degC/min\n");
  REQUIRE(p.steps.size() == 4);
  const auto& down = std::get<RampStep>(p.steps[1].action);
  CHECK(down.target_c == 10.0);
  CHECK(down.rate_c_per_min == 1.0);
  CHECK(down.target_column == 9);  // "ramp to " is 8 characters
  CHECK(down.rate_column == 17);   // "ramp to 10 C at " is 16
  CHECK(std::get<RampStep>(p.steps[2].action).rate_c_per_min == Approx(0.5));  // 30 / 60
  CHECK(std::get<RampStep>(p.steps[3].action).target_c == -5.0);
  // The direction comes from the target: 20 -> 10 cools, 10 -> 30 heats, 30 -> -5 cools.
  const auto pts = nominal_setpoints(p, 1.0);
  CHECK(pts[1].phase == Phase::cooling);
  // The second ramp starts after the first's 600 s (10 degC at 1 degC/min).
  CHECK(pts[601].phase == Phase::heating);
  CHECK(pts[601].step_index == 2);
}

TEST_CASE("settle has defaults and takes its clauses in any order") {
  const auto p = parse_ok(
      "setpoint 20 C\n"
      "settle within 0.2 C for 5 min\n"
      "settle within 0.5 C on coil slope 0.05 C/min for 10 min timeout 1 h\n"
      "settle within 0.5 degC for 10 min timeout 90 min slope 3 C/h on coil\n"
      "settle within 1 C on chamber for 20 s\n");
  REQUIRE(p.steps.size() == 5);
  const auto& plain = std::get<SettleStep>(p.steps[1].action);
  CHECK(p.steps[1].kind() == StepKind::settle);
  CHECK(plain.band_c == 0.2);
  CHECK(plain.on == SettleOn::chamber);
  CHECK_FALSE(plain.max_slope_c_per_min.has_value());
  CHECK(plain.stable_s == 300.0);
  CHECK(plain.timeout_s == 7200.0);  // the documented default, 2 h

  const auto& full = std::get<SettleStep>(p.steps[2].action);
  CHECK(full.band_c == 0.5);
  CHECK(full.on == SettleOn::coil);
  REQUIRE(full.max_slope_c_per_min.has_value());
  CHECK(*full.max_slope_c_per_min == 0.05);
  CHECK(full.stable_s == 600.0);
  CHECK(full.timeout_s == 3600.0);

  const auto& shuffled = std::get<SettleStep>(p.steps[3].action);
  CHECK(shuffled.on == SettleOn::coil);
  CHECK(*shuffled.max_slope_c_per_min == Approx(0.05));  // 3 C/h = 0.05 C/min
  CHECK(shuffled.timeout_s == 5400.0);

  CHECK(std::get<SettleStep>(p.steps[4].action).on == SettleOn::chamber);
}

TEST_CASE("the issue's example parses, with comments, blank lines and CRLF") {
  const auto p = parse_ok(
      "# exp: an example\r\n"
      "\r\n"
      "setpoint 20 C\r\n"
      "settle within 0.2 C for 5 min      # wait until the chamber is stable\r\n"
      "   hold 10 min\r\n"
      "\tramp to 10 C at 1 C/min\r\n"
      "hold 20 min");  // no final newline
  REQUIRE(p.steps.size() == 5);
  CHECK(p.source_name == "t.profile");
  CHECK(p.steps[0].line == 3);
  CHECK(p.steps[1].line == 4);
  CHECK(p.steps[3].line == 6);
  CHECK(p.steps[4].line == 7);
  CHECK(p.steps[3].text == "\tramp to 10 C at 1 C/min");  // as written, without the CR
  // settle 300 s + hold 600 s + ramp 20 -> 10 at 1 degC/min 600 s + hold 1200 s = 2700 s.
  CHECK(p.nominal_duration_s() == 2700.0);
}

TEST_CASE("a wrong temperature unit names the line, column, value and what was found") {
  const auto e = parse_err(
      "setpoint 20 C\n"
      "settle within 0.2 C for 5 min\n"
      "hold 10 min\n"
      "ramp to 10 F at 1 C/min\n");
  // "ramp to 10 " is 11 characters: F is in column 12 of line 4.
  CHECK(e.source == "t.profile");
  CHECK(e.line == 4);
  CHECK(e.column == 12);
  CHECK(e.message == "expected a temperature unit 'C' after '10', found 'F'");
  CHECK(e.line_text == "ramp to 10 F at 1 C/min");
  CHECK(e.to_string() == "t.profile:4:12: expected a temperature unit 'C' after '10', found 'F'");
  CHECK(e.excerpt() == "ramp to 10 F at 1 C/min\n           ^");  // 11 spaces, then the caret
}

TEST_CASE("temperature unit errors: K, a missing unit, an unknown word") {
  SECTION("kelvin") {
    const auto e = parse_err("setpoint 300 K\n");
    CHECK(e.line == 1);
    CHECK(e.column == 14);
    CHECK(e.message == "expected a temperature unit 'C' after '300', found 'K'");
  }
  SECTION("missing: points just past the number") {
    const auto e = parse_err("setpoint 20\n");
    CHECK(e.column == 12);  // "setpoint 20" ends in column 11
    CHECK(e.message == "expected a temperature unit 'C' after '20', found end of line");
  }
  SECTION("unknown word") {
    const auto e = parse_err("setpoint 20 celsius\n");
    CHECK(e.column == 13);
    CHECK(e.message == "expected a temperature unit 'C' after '20', found 'celsius'");
  }
  SECTION("lower-case c is not a unit") {
    CHECK(parse_err("setpoint 20 c\n").column == 13);
  }
  SECTION("in a settle band") {
    const auto e = parse_err("setpoint 20 C\nsettle within 0.2 K for 5 min\n");
    CHECK(e.line == 2);
    CHECK(e.column == 19);  // "settle within 0.2 " is 18 characters
  }
}

TEST_CASE("duration and rate unit errors") {
  SECTION("duration") {
    const auto e = parse_err("setpoint 20 C\nhold 10 m\n");
    CHECK(e.line == 2);
    CHECK(e.column == 9);
    CHECK(e.message == "expected a duration unit 's', 'min' or 'h' after '10', found 'm'");
  }
  SECTION("rate") {
    const auto e = parse_err("setpoint 20 C\nramp to 10 C at 1 C/s\n");
    CHECK(e.column == 19);  // "ramp to 10 C at 1 " is 18 characters
    CHECK(e.message == "expected a rate unit 'C/min' or 'C/h' after '1', found 'C/s'");
  }
  SECTION("an exponent is not part of a number") {
    // "1e3" reads as the number 1 followed by the word "e3", which is not a unit.
    const auto e = parse_err("setpoint 20 C\nhold 1e3 s\n");
    CHECK(e.column == 7);
    CHECK(e.message == "expected a duration unit 's', 'min' or 'h' after '1', found 'e3'");
  }
}

TEST_CASE("missing numbers and keywords") {
  SECTION("no number") {
    const auto e = parse_err("setpoint 20 C\nhold min\n");
    CHECK(e.line == 2);
    CHECK(e.column == 6);
    CHECK(e.message == "expected a duration after 'hold', found 'min'");
  }
  SECTION("nothing at all") {
    const auto e = parse_err("setpoint\n");
    CHECK(e.column == 9);
    CHECK(e.message == "expected a temperature after 'setpoint', found end of line");
  }
  SECTION("ramp without 'to'") {
    const auto e = parse_err("setpoint 20 C\nramp 10 C at 1 C/min\n");
    CHECK(e.column == 6);
    CHECK(e.message == "expected 'to' after 'ramp', found '10'");
  }
  SECTION("ramp without 'at'") {
    const auto e = parse_err("setpoint 20 C\nramp to 10 C 1 C/min\n");
    CHECK(e.column == 14);
    CHECK(e.message == "expected 'at' after 'C', found '1'");
  }
  SECTION("settle without 'for'") {
    const auto e = parse_err("setpoint 20 C\nsettle within 0.2 C on coil\n");
    CHECK(e.line == 2);
    CHECK(e.column == 28);  // "settle within 0.2 C on coil" is 27 characters
    CHECK_THAT(e.message, Catch::StartsWith("'settle' needs 'for <duration>'"));
  }
  SECTION("settle on something else") {
    const auto e = parse_err("setpoint 20 C\nsettle within 0.2 C on gyro for 5 min\n");
    CHECK(e.column == 24);
    CHECK(e.message == "expected 'chamber' or 'coil' after 'on', found 'gyro'");
  }
}

TEST_CASE("unknown statements and trailing words") {
  SECTION("unknown statement") {
    const auto e = parse_err("setpoint 20 C\n  wait 10 min\n");
    CHECK(e.line == 2);
    CHECK(e.column == 3);
    CHECK(e.message ==
          "unknown statement 'wait'; expected 'setpoint', 'hold', 'ramp', 'settle' or 'rate'");
  }
  SECTION("extra words after a statement") {
    const auto e = parse_err("setpoint 20 C\nhold 10 min please\n");
    CHECK(e.column == 13);
    CHECK(e.message == "unexpected 'please' after the end of the 'hold' statement");
  }
  SECTION("a second duration") {
    CHECK(parse_err("setpoint 20 C\nhold 10 min 30 s\n").column == 13);
  }
  SECTION("an unknown settle clause") {
    const auto e = parse_err("setpoint 20 C\nsettle within 0.2 C for 5 min quickly\n");
    CHECK(e.column == 31);
    CHECK_THAT(e.message, Catch::StartsWith("unexpected 'quickly' in 'settle'"));
  }
  SECTION("a clause given twice") {
    const auto e = parse_err("setpoint 20 C\nsettle within 0.2 C for 5 min for 6 min\n");
    CHECK(e.column == 31);
    CHECK(e.message == "'for' given twice in one 'settle' (first at column 21)");
  }
}

TEST_CASE("values that must be positive") {
  SECTION("negative duration") {
    const auto e = parse_err("setpoint 20 C\nhold -5 min\n");
    CHECK(e.line == 2);
    CHECK(e.column == 6);
    CHECK(e.message == "a duration must be positive, found '-5'");
  }
  SECTION("zero rate") {
    const auto e = parse_err("setpoint 20 C\nramp to 10 C at 0 C/min\n");
    CHECK(e.column == 17);
    CHECK(e.message ==
          "a ramp rate must be positive (the direction comes from the target), found '0'");
  }
  SECTION("negative rate") {
    CHECK(parse_err("setpoint 20 C\nramp to 10 C at -1 C/min\n").column == 17);
  }
  SECTION("zero band") {
    const auto e = parse_err("setpoint 20 C\nsettle within 0 C for 5 min\n");
    CHECK(e.column == 15);
    CHECK(e.message == "a settle band must be positive, found '0'");
  }
  SECTION("negative timeout") {
    CHECK(parse_err("setpoint 20 C\nsettle within 0.2 C for 5 min timeout -1 h\n").column == 39);
  }
  SECTION("a timeout shorter than the settle time can never be met") {
    const auto e = parse_err("setpoint 20 C\nsettle within 0.2 C for 10 min timeout 5 min\n");
    CHECK(e.column == 40);
    CHECK(e.message == "the settle can never be met: its timeout (300 s) is shorter than its "
                       "'for' time (600 s)");
  }
  SECTION("a settle longer than the default timeout needs its own") {
    // 3 h > the 2 h default: refused at the 'for' value.
    const auto e = parse_err("setpoint 20 C\nsettle within 0.2 C for 3 h\n");
    CHECK(e.column == 25);
  }
}

TEST_CASE("a profile must open with a setpoint") {
  SECTION("hold first, after comments and blank lines") {
    const auto e = parse_err("# a profile\n\n  hold 10 min\nsetpoint 20 C\n");
    CHECK(e.line == 3);
    CHECK(e.column == 3);
    CHECK(e.message == "a profile must open with 'setpoint <T> C', found 'hold'");
  }
  SECTION("no statements") {
    const auto e = parse_err("# nothing here\n\n");
    CHECK(e.line == 1);
    CHECK_THAT(e.message, Catch::Contains("must open with 'setpoint <T> C'"));
  }
  SECTION("an empty text") {
    CHECK(parse_err("").line == 1);
  }
}

TEST_CASE("a ramp to the current setpoint is refused") {
  const auto e = parse_err("setpoint 20 C\nhold 1 min\nramp to 20 C at 1 C/min\n");
  CHECK(e.line == 3);
  CHECK(e.column == 9);
  CHECK(e.message == "this ramp does not move the setpoint: it is already 20 degC here");
}

TEST_CASE("excerpt keeps tabs so the caret lines up") {
  const auto e = parse_err("setpoint 20 C\n\thold 10 x\n");
  CHECK(e.column == 10);  // tab, "hold 10 " = 1 + 8 characters
  CHECK(e.excerpt() == "\thold 10 x\n\t        ^");
}
