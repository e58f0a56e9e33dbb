// The serials' verdicts in the store (schema 8, issue 24): one row per decision, the serial's
// verdict its latest, and every row checked before it is kept.
#include <catch2/catch.hpp>

#include "fogbench/storage/errors.hpp"
#include "fogbench/storage/models.hpp"
#include "fogbench/storage/plans.hpp"
#include "fogbench/storage/runs.hpp"
#include "fogbench/storage/samples.hpp"
#include "fogbench/storage/store.hpp"
#include "fogbench/storage/verdict.hpp"

using namespace fogbench;
using namespace fogbench::storage;

namespace {
Store mem() {
  auto s = Store::open(":memory:");
  REQUIRE(s.has_value());
  return std::move(*s);
}

std::int64_t imported_run(Store& s, const std::string& serial) {
  model::RunData d;
  d.name = "small";
  for (int i = 0; i < 5; ++i) {
    d.time_s.push_back(i);
    d.gyro_dph.push_back(0.1 * i);
    d.t1_c.push_back(20.0);
    d.t2_c.push_back(20.5);
  }
  ImportOptions o;
  o.serial = serial;
  o.purpose = Purpose::verify;
  auto id = s.import_run(d, o);
  REQUIRE(id.has_value());
  return *id;
}

std::int64_t model_of(Store& s, const std::string& serial) {
  NewModel m;
  m.serial = serial;
  m.model_json = "{}";
  auto ref = s.put_model(m);
  REQUIRE(ref.has_value());
  return ref->id;
}
}  // namespace

TEST_CASE("verdicts: the serial's verdict is its latest decision, whatever rule made it") {
  Store s = mem();
  const auto run1 = imported_run(s, "FOG-1");
  const auto run2 = imported_run(s, "FOG-1");
  const auto model = model_of(s, "FOG-1");
  CHECK_FALSE(s.latest_verdict("FOG-1")->has_value());

  NewVerdict a;
  a.serial = "FOG-1";
  a.run_id = run1;
  a.model_id = model;
  a.verdict = "pass";
  a.rule = "analysis";
  a.limits_json = R"([{"limit":"comp_raw < 0.2","value":0.1,"met":true}])";
  REQUIRE(s.put_verdict(a).has_value());
  auto first = s.latest_verdict("FOG-1");
  REQUIRE(first->has_value());
  CHECK((*first)->verdict == "pass");
  CHECK((*first)->rule == "analysis");
  CHECK((*first)->model_id == model);
  CHECK_FALSE((*first)->decided_at.empty());

  auto plan = s.create_plan(NewPlan{"strict", "strict.plan", "step exp1 verify\n", {"FOG-1"}, "running"}, "plan.start", "{}");
  REQUIRE(plan.has_value());
  NewVerdict b = a;
  b.run_id = run2;
  b.verdict = "fail";
  b.rule = "plan";
  b.plan_id = *plan;
  b.plan_name = "strict";
  b.plan_sha256 = std::string(64, 'f');
  b.reasons_json = R"j(["comp_raw = 0.1, limit comp_raw < 0.05 (line 2)"])j";
  REQUIRE(s.put_verdict(b).has_value());
  auto latest = s.latest_verdict("FOG-1");
  REQUIRE(latest->has_value());
  CHECK((*latest)->verdict == "fail");
  CHECK((*latest)->plan_id == *plan);
  CHECK((*latest)->plan_name == "strict");
  CHECK((*latest)->reasons_json == b.reasons_json);
  // Each run keeps what it decided.
  REQUIRE(s.run_verdicts(run1)->size() == 1);
  CHECK(s.run_verdicts(run1)->at(0).verdict == "pass");
  CHECK(s.run_verdicts(run2)->at(0).verdict == "fail");
  CHECK_FALSE(s.latest_verdict("FOG-2")->has_value());
}

TEST_CASE("verdicts: a verdict that does not hold together is refused and nothing is stored") {
  Store s = mem();
  const auto run = imported_run(s, "FOG-1");
  const auto other_model = model_of(s, "FOG-2");
  NewVerdict v;
  v.serial = "FOG-1";
  v.run_id = run;
  v.verdict = "pass";
  v.rule = "analysis";
  auto refused = [&](NewVerdict bad, const std::string& says) {
    auto r = s.put_verdict(bad);
    REQUIRE_FALSE(r.has_value());
    INFO(r.error().message);
    CHECK(r.error().message.find(says) != std::string::npos);
  };
  NewVerdict x = v;
  x.verdict = "passed";
  refused(x, "verdict 'passed'");
  x = v;
  x.rule = "config";
  refused(x, "rule 'config'");
  x = v;
  x.rule = "plan";  // without its plan
  refused(x, "plan id");
  x = v;
  x.plan_name = "strict";  // a plan's name on an analysis verdict
  refused(x, "plan name");
  x = v;
  x.limits_json = "{}";
  refused(x, "limits_json");
  x = v;
  x.reasons_json = "[";
  refused(x, "reasons_json");
  x = v;
  x.serial = "FOG-9";  // not the run's unit
  refused(x, "is FOG-1");
  x = v;
  x.unit_index = 3;
  CHECK(s.put_verdict(x).error().code == StoreErrc::not_found);
  x = v;
  x.model_id = other_model;
  refused(x, "FOG-2's");
  CHECK(s.run_verdicts(run)->empty());
  CHECK(s.put_verdict(v).has_value());
}

TEST_CASE("verdicts: the same decision twice is one row, a decision after another is a new one") {
  Store s = mem();
  const auto run = imported_run(s, "FOG-2");
  const auto model = model_of(s, "FOG-2");
  NewVerdict v;
  v.serial = "FOG-2";
  v.run_id = run;
  v.model_id = model;
  v.verdict = "fail";
  v.rule = "analysis";
  v.limits_json = R"([{"limit":"comp_raw < 0.2","value":0.3,"met":false}])";
  v.reasons_json = R"(["comp/raw 30.0 % >= 20 %"])";
  const auto first = s.put_verdict(v);
  REQUIRE(first.has_value());
  // Decided again, as after a restart between the decision and what followed it: one row.
  const auto again = s.put_verdict(v);
  REQUIRE(again.has_value());
  CHECK(*again == *first);
  CHECK(s.run_verdicts(run)->size() == 1);
  // Not the same decision: another value of a limit is a new row, and the latest.
  NewVerdict other = v;
  other.limits_json = R"([{"limit":"comp_raw < 0.2","value":0.31,"met":false}])";
  const auto second = s.put_verdict(other);
  REQUIRE(second.has_value());
  CHECK(*second != *first);
  // The first decision once more after another one: a new decision (the latest is not it).
  const auto third = s.put_verdict(v);
  REQUIRE(third.has_value());
  CHECK(*third != *first);
  CHECK(*third != *second);
  CHECK(s.run_verdicts(run)->size() == 3);
  CHECK(s.latest_verdict("FOG-2")->value().id == *third);
}
