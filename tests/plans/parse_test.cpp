// The plan language (docs/plans.md): what parses, what each statement gives, and the errors
// that name the line and column; the shipped plans parse.
#include <catch2/catch.hpp>

#include <cmath>
#include <fstream>
#include <sstream>

#include "fogbench/plans/plan.hpp"

using namespace fogbench::plans;

namespace {
PlanError error_of(std::string_view text) {
  auto p = parse_plan(text, "t.plan");
  REQUIRE_FALSE(p.has_value());
  return p.error();
}
std::string read(const std::string& rel) {
  std::ifstream in(std::string(FOGBENCH_SOURCE_DIR) + "/" + rel);
  REQUIRE(in);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}
}  // namespace

TEST_CASE("a plan gives its steps and limits in order") {
  auto p = parse_plan(
      "# comment\nplan batch-7\nstep exp1 fit\r\nstep exp2 verify   # a comment\nstep soak1 soak\n"
      "limit comp_raw < 0.2\nlimit sensitivity d(T1)@60 within -3 .. -2 continue\n"
      "limit fail_s <= 60 s retest\nlimit arw < 0.01 deg/sqrt(h)\n",
      "t.plan");
  REQUIRE(p.has_value());
  CHECK(p->name == "batch-7");
  REQUIRE(p->steps.size() == 3);
  CHECK(p->steps[0].profile == "exp1");
  CHECK(p->steps[0].purpose == StepPurpose::fit);
  CHECK(p->steps[1].purpose == StepPurpose::verify);
  CHECK(p->steps[2].purpose == StepPurpose::soak);
  CHECK(p->steps[2].line == 5);
  REQUIRE(p->limits.size() == 4);
  CHECK(p->limits[0].on_fail == OnFail::stop);
  CHECK(p->limits[0].met(0.19));
  CHECK_FALSE(p->limits[0].met(0.2));
  CHECK_FALSE(p->limits[0].met(std::nan("")));
  CHECK(p->limits[1].term == "d(T1)");  // the name without the lag, as the model prints it
  CHECK(p->limits[1].on_fail == OnFail::go_on);
  CHECK(p->limits[1].met(-2.5));
  CHECK_FALSE(p->limits[1].met(-1.9));
  CHECK(p->limits[1].describe() == "sensitivity d(T1) within -3 .. -2");
  CHECK(p->limits[2].on_fail == OnFail::retest);
  CHECK(p->limits[2].met(60.0));
  CHECK(p->limits[2].describe() == "fail_s <= 60 s");
  CHECK(p->limits[3].line == 9);
}

TEST_CASE("the name defaults to the source's stem") {
  auto p = parse_plan("step exp1 fit\n", "dir/night.plan");
  REQUIRE(p.has_value());
  CHECK(p->name == "night");
}

TEST_CASE("a source's stem that is no plan name is refused, not stored as the name") {
  for (const std::string& source : {std::string("dir/\x1b]0;owned\x07.plan"), std::string("my night.plan"),
                                   std::string(100000, 'n') + ".plan", std::string("dir/.plan")}) {
    INFO(source.size());
    auto p = parse_plan("step exp1 fit\n", source);
    REQUIRE_FALSE(p.has_value());
    CHECK(p.error().message.find("add a line 'plan <name>'") != std::string::npos);
  }
  // With a `plan` line the file's name does not matter.
  auto named = parse_plan("plan night\nstep exp1 fit\n", "my night.plan");
  REQUIRE(named.has_value());
  CHECK(named->name == "night");
}

TEST_CASE("errors name the line and column of what is wrong") {
  auto e = error_of("step exp1 fit\nlimit drift_rate < 3\n");
  CHECK(e.line == 2);
  CHECK(e.column == 7);
  CHECK(e.message.find("unknown measurement 'drift_rate'") != std::string::npos);
  CHECK(e.to_string().starts_with("t.plan:2:7: unknown measurement"));
  CHECK(e.excerpt() == "limit drift_rate < 3\n      ^");

  e = error_of("step exp1 calibrate\n");
  CHECK(e.line == 1);
  CHECK(e.column == 11);
  CHECK(e.message == "expected a purpose 'fit', 'verify', 'soak' or 'custom', found 'calibrate'");

  e = error_of("step exp1 fit\nlimit comp_raw < 0.2\n");  // no verify step measures it
  CHECK(e.line == 2);
  CHECK(e.message.find("no step of this plan measures comp_raw") != std::string::npos);

  e = error_of("step exp1 fit\nstep exp2 verify\nlimit comp_raw < 0.2\nlimit comp_raw < 0.3\n");
  CHECK(e.line == 4);
  CHECK(e.message.find("given twice (first on line 3)") != std::string::npos);

  e = error_of("step exp1 fit\nlimit sensitivity d(T9) within 1 .. 2\n");
  CHECK(e.line == 2);
  CHECK(e.message.find("not a term") != std::string::npos);

  e = error_of("step exp1 fit\nlimit sensitivity grad within 2 .. 1\n");
  CHECK(e.line == 2);
  CHECK(e.column == 36);

  e = error_of("step exp1 fit\nstep exp2 verify\nlimit fail_s < 60 min\n");
  CHECK(e.column == 19);
  CHECK(e.message.find("the unit 's'") != std::string::npos);

  e = error_of("step exp1 fit\nstep exp2 verify\nlimit comp_raw < 0.2 stop now\n");
  CHECK(e.message == "unexpected 'now' after the end of the 'limit' statement");

  e = error_of("step exp1 fit\nstep exp2 verify\nlimit comp_raw < .2\n");
  CHECK(e.message == "expected a number after '<', found '.2'");

  e = error_of("wait 5\n");
  CHECK(e.message == "unknown statement 'wait'; expected 'plan', 'step' or 'limit'");

  e = error_of("# nothing\n");
  CHECK(e.line == 0);
  CHECK(e.to_string() == "t.plan: a plan needs at least one 'step <profile> <purpose>'");

  e = error_of("step exp1 fit\nplan late\n");
  CHECK(e.message == "'plan <name>' must come before the steps and limits");
}

TEST_CASE("the shipped plans parse") {
  for (const char* name : {"paper", "qualification"}) {
    INFO(name);
    auto p = parse_plan(read(std::string("plans/") + name + ".plan"), std::string(name) + ".plan");
    if (!p) FAIL(p.error().to_string());
    CHECK(p->name == name);
    REQUIRE(p->steps.size() == 3);
    CHECK(p->steps[0].purpose == StepPurpose::fit);
    CHECK(p->steps[1].purpose == StepPurpose::verify);
    CHECK(p->steps[2].purpose == StepPurpose::verify);
  }
  auto paper = parse_plan(read("plans/paper.plan"), "paper.plan");
  REQUIRE(paper.has_value());
  CHECK(paper->limits[0].describe() == "comp_raw < 0.2");
  CHECK(paper->limits[0].on_fail == OnFail::stop);
}

TEST_CASE("limit firmware required: a fit's model must have a firmware form, with an action, met by 1 only") {
  auto p = parse_plan("step exp1 fit\nstep exp2 verify\nlimit firmware required continue\nlimit comp_raw < 0.2\n", "t.plan");
  REQUIRE(p.has_value());
  REQUIRE(p->limits.size() == 2);
  const Limit& f = p->limits[0];
  CHECK(f.measurement == Measurement::firmware);
  CHECK(f.compare == Compare::required);
  CHECK(f.on_fail == OnFail::go_on);
  CHECK(f.line == 3);
  CHECK(f.describe() == "firmware required");
  CHECK(f.name() == "firmware");
  CHECK(f.met(1.0));
  CHECK_FALSE(f.met(0.0));
  CHECK_FALSE(f.met(std::nan("")));
  CHECK(measured_in(Measurement::firmware, StepPurpose::fit));
  CHECK_FALSE(measured_in(Measurement::firmware, StepPurpose::verify));
  // The default action is stop.
  CHECK(parse_plan("step exp1 fit\nlimit firmware required\n", "t.plan")->limits[0].on_fail == OnFail::stop);

  auto e = error_of("step exp1 fit\nlimit firmware < 1\n");
  CHECK(e.line == 2);
  CHECK(e.column == 16);
  CHECK(e.message == "expected 'required' after 'firmware', found '<'");
  e = error_of("step exp1 fit\nlimit firmware\n");
  CHECK(e.message == "expected 'required' after 'firmware', found end of line");
  e = error_of("step exp1 fit\nlimit firmware required later\n");
  CHECK(e.column == 25);
  CHECK(e.message == "expected 'stop', 'continue' or 'retest', found 'later'");
  e = error_of("step exp2 verify\nlimit firmware required\n");  // no fit step to judge it
  CHECK(e.message.find("no step of this plan measures firmware (a fit step does)") != std::string::npos);
  e = error_of("step exp1 fit\nlimit firmware required\nlimit firmware required retest\n");
  CHECK(e.message.find("given twice (first on line 2)") != std::string::npos);
}

TEST_CASE("limit sf_tc_ppm_per_c: the scale factor's temperature sensitivity, ppm/degC, in fit and verify steps") {
  auto p = parse_plan("step spin fit\nlimit sf_tc_ppm_per_c < 20 ppm/degC retest\n", "t.plan");
  REQUIRE(p.has_value());
  REQUIRE(p->limits.size() == 1);
  const Limit& l = p->limits[0];
  CHECK(l.measurement == Measurement::sf_tc_ppm_per_c);
  CHECK(l.compare == Compare::lt);
  CHECK(l.value == 20.0);
  CHECK(l.on_fail == OnFail::retest);
  CHECK(l.describe() == "sf_tc_ppm_per_c < 20 ppm/degC");
  CHECK(l.met(19.9));
  CHECK_FALSE(l.met(20.0));
  CHECK_FALSE(l.met(std::nan("")));
  CHECK(unit_of(Measurement::sf_tc_ppm_per_c) == "ppm/degC");
  CHECK(measured_in(Measurement::sf_tc_ppm_per_c, StepPurpose::fit));
  CHECK(measured_in(Measurement::sf_tc_ppm_per_c, StepPurpose::verify));
  CHECK_FALSE(measured_in(Measurement::sf_tc_ppm_per_c, StepPurpose::soak));
  CHECK_FALSE(measured_in(Measurement::sf_tc_ppm_per_c, StepPurpose::custom));
  // Without the unit, and on a verify step alone.
  CHECK(parse_plan("step spin verify\nlimit sf_tc_ppm_per_c <= 5\n", "t.plan").has_value());

  auto e = error_of("step spin fit\nlimit sf_tc_ppm_per_c < 20 ppm/C\n");
  CHECK(e.line == 2);
  CHECK(e.column == 28);
  CHECK(e.message == "expected the unit 'ppm/degC' or 'stop', 'continue', 'retest', found 'ppm/C'");
  e = error_of("step spin fit\nlimit sf_tc_ppm_per_c < twenty\n");
  CHECK(e.column == 25);
  CHECK(e.message == "expected a number after '<', found 'twenty'");
  e = error_of("step s1 soak\nlimit sf_tc_ppm_per_c < 20\n");  // no fit or verify step
  CHECK(e.line == 2);
  CHECK(e.message.find("no step of this plan measures sf_tc_ppm_per_c (a fit or verify step whose profile has rate steps does)") !=
        std::string::npos);
  e = error_of("step spin fit\nlimit sf_tc_ppm_per_c < 20\nlimit sf_tc_ppm_per_c < 10\n");
  CHECK(e.line == 3);
  CHECK(e.message == "a limit on sf_tc_ppm_per_c is given twice (first on line 2)");
  e = error_of("step spin fit\nlimit sf_tc < 20\n");
  CHECK(e.column == 7);
  CHECK(e.message.find("unknown measurement 'sf_tc'") != std::string::npos);
  CHECK(e.message.find("'sf_tc_ppm_per_c'") != std::string::npos);
}

TEST_CASE("limits sf_nonlinearity_ppm and sf_asymmetry_ppm: ppm, where the scale factor is measured") {
  auto p = parse_plan("step spin verify\nlimit sf_nonlinearity_ppm < 200 ppm continue\nlimit sf_asymmetry_ppm <= 50\n", "t.plan");
  REQUIRE(p.has_value());
  REQUIRE(p->limits.size() == 2);
  CHECK(p->limits[0].measurement == Measurement::sf_nonlinearity_ppm);
  CHECK(p->limits[0].describe() == "sf_nonlinearity_ppm < 200 ppm");
  CHECK(p->limits[0].on_fail == OnFail::go_on);
  CHECK(p->limits[1].measurement == Measurement::sf_asymmetry_ppm);
  CHECK(p->limits[1].describe() == "sf_asymmetry_ppm <= 50 ppm");
  for (auto m : {Measurement::sf_nonlinearity_ppm, Measurement::sf_asymmetry_ppm}) {
    CHECK(unit_of(m) == "ppm");
    CHECK(needs_rate_steps(m));
    CHECK(measured_in(m, StepPurpose::fit));
    CHECK(measured_in(m, StepPurpose::verify));
    CHECK_FALSE(measured_in(m, StepPurpose::soak));
  }
  CHECK(needs_rate_steps(Measurement::sf_tc_ppm_per_c));
  CHECK_FALSE(needs_rate_steps(Measurement::arw));

  auto e = error_of("step spin fit\nlimit sf_asymmetry_ppm < 50 ppm/degC\n");
  CHECK(e.line == 2);
  CHECK(e.message == "expected the unit 'ppm' or 'stop', 'continue', 'retest', found 'ppm/degC'");
  e = error_of("step s1 soak\nlimit sf_nonlinearity_ppm < 20\n");
  CHECK(e.message.find("no step of this plan measures sf_nonlinearity_ppm (a fit or verify step whose profile has rate steps does)") !=
        std::string::npos);
}
