// Rate steps (`rate <r> dps for <d>`): the rate table's sequence at a temperature plateau, parsed
// only (issue 29, point 1). Every error names the line and column.
#include <catch2/catch.hpp>

#include <string>

#include "fogbench/profiles/profile.hpp"
#include "parse_helpers.hpp"

using namespace fogbench::profiles;

using fogbench::profiles::test::parse_err;
using fogbench::profiles::test::parse_ok;

TEST_CASE("rate steps: a sequence of +-rates at each hold, in order, with their plateau") {
  const auto p = parse_ok(
      "setpoint 20 C\n"
      "hold 10 min\n"
      "rate 100 dps for 60 s\n"
      "rate -100 dps for 60 s   # the other way\n"
      "rate +10 deg/s for 1 min\n"
      "rate 0 dps for 30 s\n"
      "ramp to 40 C at 1 C/min\n"
      "hold 5 min\n"
      "rate 250.5dps for 5 min\n");
  REQUIRE(p.steps.size() == 4);  // the temperature steps are unchanged
  REQUIRE(p.rate_steps.size() == 5);
  CHECK(p.rate_steps[0].rate_dps == 100.0);
  CHECK(p.rate_steps[0].duration_s == 60.0);
  CHECK(p.rate_steps[0].plateau == 1);
  CHECK(p.rate_steps[0].line == 3);
  CHECK(p.rate_steps[0].rate_column == 6);
  CHECK(p.rate_steps[1].rate_dps == -100.0);
  CHECK(p.rate_steps[1].text == "rate -100 dps for 60 s   # the other way");
  CHECK(p.rate_steps[2].rate_dps == 10.0);
  CHECK(p.rate_steps[2].rate_column == 7);
  CHECK(p.rate_steps[2].duration_s == 60.0);
  CHECK(p.rate_steps[3].rate_dps == 0.0);
  CHECK(p.rate_steps[4].rate_dps == 250.5);
  CHECK(p.rate_steps[4].plateau == 3);
  CHECK(p.rate_steps[4].duration_s == 300.0);
  CHECK(p.nominal_duration_s() == Approx(600.0 + 1200.0 + 300.0));  // rate steps add no time
}

TEST_CASE("rate steps: errors name the line, the column and what is wrong") {
  auto e = parse_err("setpoint 20 C\nhold 10 min\nrate 100 for 60 s\n");
  CHECK(e.to_string() == "t.profile:3:10: expected a table rate unit 'dps' or 'deg/s' after '100', found 'for'");
  e = parse_err("setpoint 20 C\nhold 10 min\nrate fast dps for 60 s\n");
  CHECK(e.to_string() == "t.profile:3:6: expected a table rate in deg/s after 'rate', found 'fast'");
  e = parse_err("setpoint 20 C\nhold 10 min\nrate 100 dps 60 s\n");
  CHECK(e.to_string() == "t.profile:3:14: expected 'for' after 'dps', found '60'");
  e = parse_err("setpoint 20 C\nhold 10 min\nrate 100 dps for 60\n");
  CHECK(e.to_string() == "t.profile:3:20: expected a duration unit 's', 'min' or 'h' after '60', found end of line");
  e = parse_err("setpoint 20 C\nhold 10 min\nrate 100 dps for -5 s\n");
  CHECK(e.to_string() == "t.profile:3:18: a duration must be positive, found '-5'");
  e = parse_err("setpoint 20 C\nhold 10 min\nrate 100 dps for 60 s each\n");
  CHECK(e.to_string() == "t.profile:3:23: unexpected 'each' after the end of the 'rate' statement");
  // "+10dps" splits into two words while the line has exactly four: the words' storage grows
  // under the split (a use after free found by fuzz_profile, fuzz/regressions/profile/).
  e = parse_err("setpoint 20 C\nhold 10 min\nrate +10dps for 5\n");
  CHECK(e.to_string() == "t.profile:3:18: expected a duration unit 's', 'min' or 'h' after '5', found end of line");
  CHECK(parse_ok("setpoint 20 C\nhold 10 min\nrate +10dps for 5s\n").rate_steps.at(0).rate_dps == 10.0);
  e = parse_err("setpoint 20 C\nhold 10 min\nrate +-5 dps for 60 s\n");
  CHECK(e.line == 3);
  CHECK_THAT(e.message, Catch::StartsWith("expected a rate in deg/s after 'rate'"));
}

TEST_CASE("rate steps: only at a hold, fitting in it, and never first") {
  auto e = parse_err("rate 10 dps for 1 s\nsetpoint 20 C\n");
  CHECK(e.to_string() == "t.profile:1:1: a profile must open with 'setpoint <T> C', found 'rate'");
  e = parse_err("setpoint 20 C\nramp to 30 C at 1 C/min\nrate 10 dps for 1 min\n");
  CHECK(e.to_string() ==
        "t.profile:3:1: a rate step runs during a temperature plateau: put it after a 'hold' (line 2 is a 'ramp')");
  e = parse_err("setpoint 20 C\nsettle within 1 C for 5 min\nrate 10 dps for 1 min\n");
  CHECK(e.line == 3);
  CHECK_THAT(e.message, Catch::EndsWith("(line 2 is a 'settle')"));
  e = parse_err("setpoint 20 C\nhold 2 min\nrate 10 dps for 1 min\nrate -10 dps for 61 s\n");
  CHECK(e.to_string() == "t.profile:4:1: the rate sequence does not fit in its plateau: 60 s before this step and "
                         "its 61 s exceed the hold of 120 s on line 2");
  CHECK(e.excerpt() == "rate -10 dps for 61 s\n^");
}

TEST_CASE("rate steps: the table's limit, naming the line and the rate") {
  const auto p = parse_ok("setpoint 20 C\nhold 10 min\nrate 100 dps for 60 s\nrate -400 dps for 60 s\n");
  CHECK(check_rate_limits(p, 400.0));
  auto e = check_rate_limits(p, 300.0);
  REQUIRE_FALSE(e);
  CHECK(e.error().to_string() == "t.profile:4:6: table rate -400 deg/s is beyond the rate table's limit +-300 deg/s");
  e = check_rate_limits(p, 0.0);
  REQUIRE_FALSE(e);
  CHECK(e.error().to_string() == "t.profile: the rate table's limit must be a positive max_rate_dps, got 0 deg/s");
}
