// The analysis rule's verdict of a three-axis unit (verdict.cpp, from_axis_verifications): the
// worst of its axes, each judged as a one-axis unit is, stored once with each axis' evidence;
// a one-axis unit's verdict has no axes and reads as before. The plan rule's (from_plan) carries
// a three-axis unit's evidence per axis the same way.
#include <catch2/catch.hpp>

#include "../../daemon/src/verdict.hpp"

using namespace fogbench;
using namespace fogbench::daemon;
using nlohmann::json;

namespace {
// A stored verification result as analysis::verify keeps it: model::to_json's fields that the
// rule reads, with the limits in effect.
json axis_result(double ratio, bool pass, const char* axis) {
  return {{"ratio", ratio}, {"threshold", 0.2}, {"noise_factor", 1.1}, {"max_noise_factor", 3.0},
          {"longest_fail_s", 0.0}, {"max_fail_s", 600.0}, {"pass", pass}, {"verdict", pass ? "pass" : "fail"},
          {"reasons", pass ? json::array() : json::array({"compensated std / raw std 0.9 >= 0.2"})}, {"axis", axis}};
}
}  // namespace

TEST_CASE("verdict axes: the worst verdict wins, fail over incomplete over marginal over pass") {
  CHECK(verdict::worst("pass", "pass") == "pass");
  CHECK(verdict::worst("pass", "marginal") == "marginal");
  CHECK(verdict::worst("marginal", "pass") == "marginal");
  CHECK(verdict::worst("incomplete", "marginal") == "incomplete");
  CHECK(verdict::worst("fail", "incomplete") == "fail");
  CHECK(verdict::worst("pass", "fail") == "fail");
}

TEST_CASE("verdict axes: y fails, x and z pass: the unit fails on x's model with each axis' evidence") {
  const std::vector<verdict::AxisVerification> axes{
      {"x", 11, axis_result(0.10, true, "x")}, {"y", 12, axis_result(0.90, false, "y")}, {"z", 13, axis_result(0.11, true, "z")}};
  const storage::NewVerdict v = verdict::from_axis_verifications("FOG-1", 7, 0, axes);
  CHECK(v.verdict == "fail");
  CHECK(v.rule == "analysis");
  CHECK(v.run_id == 7);
  REQUIRE(v.model_id.has_value());
  CHECK(*v.model_id == 11);  // x's: the serial's current model, the one its certificate names

  const json limits = json::parse(v.limits_json);
  REQUIRE(limits.size() == 9);  // three checks per axis
  int y_failed = 0, met = 0;
  for (const auto& l : limits) {
    if (l["axis"] == "y" && l["met"] == false) ++y_failed;
    if (l["met"] == true) ++met;
  }
  CHECK(y_failed == 1);  // y's ratio 0.9 against 0.2; its noise and failing-interval checks met
  CHECK(met == 8);
  CHECK(json::parse(v.reasons_json) == json::array({"axis y: compensated std / raw std 0.9 >= 0.2"}));

  const json evidence = json::parse(v.axes_json);
  REQUIRE(evidence.size() == 3);
  CHECK(evidence[0]["axis"] == "x");
  CHECK(evidence[0]["verdict"] == "pass");
  CHECK(evidence[1]["verdict"] == "fail");
  CHECK(evidence[1]["model_id"] == 12);
  CHECK(evidence[2]["verdict"] == "pass");
  CHECK(evidence[1]["limits"].size() == 3);

  // As the socket shows it: `axes` for this unit.
  storage::VerdictRecord rec;
  static_cast<storage::NewVerdict&>(rec) = v;
  rec.id = 1;
  const json shown = verdict::to_json(rec);
  CHECK(shown["verdict"] == "fail");
  CHECK(shown["axes"] == evidence);
}

TEST_CASE("verdict axes: every axis passing passes, and a one-axis verdict shows no axes") {
  const storage::NewVerdict all = verdict::from_axis_verifications(
      "FOG-1", 7, 0, {{"x", 1, axis_result(0.1, true, "x")}, {"y", 2, axis_result(0.1, true, "y")}, {"z", 3, axis_result(0.1, true, "z")}});
  CHECK(all.verdict == "pass");
  CHECK(json::parse(all.reasons_json).empty());

  const storage::NewVerdict one = verdict::from_verification("FOG-2", 8, 0, 4, axis_result(0.1, true, "x"));
  CHECK(one.axes_json.empty());
  storage::VerdictRecord rec;
  static_cast<storage::NewVerdict&>(rec) = one;
  CHECK_FALSE(verdict::to_json(rec).contains("axes"));
  for (const auto& l : json::parse(one.limits_json)) CHECK_FALSE(l.contains("axis"));
}

namespace {
// A plan runner's progress entry of a three-axis unit after a verify step (plan_runner.cpp's
// judge): comp_raw judged on x, y and z, each with its `axis`, and each axis' evidence.
json plan_unit_three_axes(const char* unit_verdict, const char* y_verdict, double y_ratio) {
  json measurements = json::array();
  for (const auto& [axis, ratio] : std::vector<std::pair<const char*, double>>{{"x", 0.12}, {"y", y_ratio}, {"z", 0.13}})
    measurements.push_back({{"step", 2}, {"profile", "exp2"}, {"run_id", 9}, {"measurement", "comp_raw"}, {"value", ratio},
                            {"limit", "comp_raw < 0.2"}, {"line", 4}, {"met", ratio < 0.2}, {"on_fail", "stop"},
                            {"attempt", 1}, {"axis", axis}});
  const json y_reasons = std::string(y_verdict) == "fail"
                             ? json::array({"step 2 (exp2, run 9): comp_raw = 0.82, limit comp_raw < 0.2 (line 4)"})
                             : json::array();
  return {{"serial", "FOG-3"},
          {"verdict", unit_verdict},
          {"measurements", measurements},
          {"reasons", std::string(y_verdict) == "fail"
                          ? json::array({"step 2 (exp2, run 9): axis y: comp_raw = 0.82, limit comp_raw < 0.2 (line 4)"})
                          : json::array()},
          {"axis_evidence",
           {{"x", {{"verdict", "pass"}, {"reasons", json::array()}}},
            {"y", {{"verdict", y_verdict}, {"reasons", y_reasons}}},
            {"z", {{"verdict", "pass"}, {"reasons", json::array()}}}}}};
}
const json kPlanRuns = json::array({{{"run_id", 8}, {"units", {"FOG-3"}}}, {{"run_id", 9}, {"units", {"FOG-3"}}}});
}  // namespace

TEST_CASE("verdict axes: a plan's three-axis unit failed on y carries each axis' evidence, its worst the plan's verdict") {
  const auto v = verdict::from_plan(5, "axes", "plan axes\n", plan_unit_three_axes("fail", "fail", 0.82), kPlanRuns, 21,
                                    {{"x", 21}, {"y", 22}, {"z", 23}});
  REQUIRE(v.has_value());
  CHECK(v->verdict == "fail");
  CHECK(v->rule == "plan");
  CHECK(v->run_id == 9);
  const json axes = json::parse(v->axes_json);
  REQUIRE(axes.size() == 3);
  std::string worst_of_axes = "pass";
  for (const auto& a : axes) worst_of_axes = verdict::worst(worst_of_axes, a["verdict"].get<std::string>());
  CHECK(worst_of_axes == v->verdict);  // one rule: the unit's verdict is the worst of its axes'
  CHECK(axes[0]["axis"] == "x");
  CHECK(axes[0]["verdict"] == "pass");
  CHECK(axes[1]["verdict"] == "fail");
  CHECK(axes[1]["model_id"] == 22);  // y's own model, not x's
  CHECK(axes[2]["model_id"] == 23);
  // Each axis' limits are its own measurements only.
  REQUIRE(axes[1]["limits"].size() == 1);
  CHECK(axes[1]["limits"][0]["value"] == 0.82);
  CHECK(axes[1]["limits"][0]["met"] == false);
  CHECK(axes[1]["reasons"].size() == 1);
  CHECK(axes[0]["reasons"].empty());
  // The unit's limits are every axis' (three measurements), as the analysis rule's are.
  CHECK(json::parse(v->limits_json).size() == 3);
}

TEST_CASE("verdict axes: a plan that ended first leaves a three-axis unit's unfailed axes incomplete, and a one-axis plan unit has no axes") {
  const auto v = verdict::from_plan(5, "axes", "plan axes\n", plan_unit_three_axes("incomplete", "marginal", 0.1), kPlanRuns,
                                    21, {{"x", 21}});
  REQUIRE(v.has_value());
  CHECK(v->verdict == "incomplete");
  const json axes = json::parse(v->axes_json);
  REQUIRE(axes.size() == 3);
  for (const auto& a : axes) CHECK(a["verdict"] == "incomplete");  // marginal y too: the plan did not finish it
  CHECK(axes[1]["model_id"].is_null());  // no y model given: shown as none, never x's

  json one = plan_unit_three_axes("pass", "pass", 0.1);
  one.erase("axis_evidence");
  for (auto& m : one["measurements"]) m.erase("axis");
  const auto v1 = verdict::from_plan(5, "axes", "plan axes\n", one, kPlanRuns, 21);
  REQUIRE(v1.has_value());
  CHECK(v1->verdict == "pass");
  CHECK(v1->axes_json.empty());
}

TEST_CASE("verdict axes: a three-axis unit dropped on y before the plan's last step leaves x and z incomplete, not pass") {
  json unit = plan_unit_three_axes("fail", "fail", 0.82);
  unit["axis_evidence"]["z"]["verdict"] = "marginal";
  unit["dropped_at_step"] = 2;  // the plan runner's mark: steps after 2 did not run
  const auto v = verdict::from_plan(5, "axes", "plan axes\n", unit, kPlanRuns, 21, {{"x", 21}, {"y", 22}, {"z", 23}});
  REQUIRE(v.has_value());
  CHECK(v->verdict == "fail");
  const json axes = json::parse(v->axes_json);
  REQUIRE(axes.size() == 3);
  CHECK(axes[0]["verdict"] == "incomplete");
  CHECK(axes[1]["verdict"] == "fail");  // the axis that failed keeps its fail
  CHECK(axes[2]["verdict"] == "incomplete");  // marginal so far, not finished either
  REQUIRE(axes[0]["reasons"].size() == 1);
  CHECK_THAT(axes[0]["reasons"][0].get<std::string>(), Catch::Contains("dropped at step 2"));
  CHECK(axes[1]["reasons"].size() == 1);  // y's own reason only
}
