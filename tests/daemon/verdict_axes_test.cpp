// The analysis rule's verdict of a three-axis unit (verdict.cpp, from_axis_verifications): the
// worst of its axes, each judged as a one-axis unit is, stored once with each axis' evidence;
// a one-axis unit's verdict has no axes and reads as before.
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
