// Per-axis models and verdicts in the store (schema 14, issue 29 point 3): a model's axis, the
// current model of each axis of a serial, a three-axis verdict's per-axis evidence, and a
// version 13 file upgraded with its models and verdicts one-axis as before.
#include <catch2/catch.hpp>

#include "fogbench/storage/errors.hpp"
#include "fogbench/storage/models.hpp"
#include "fogbench/storage/verdict.hpp"
#include "store_fixture.hpp"

using namespace fogbench;
using namespace fogbench::storage;
using namespace fogbench::storage::testing;
using Catch::Matchers::Contains;

namespace {

std::int64_t put_axis_model(Store& store, const std::string& serial, const std::string& axis) {
  NewModel m;
  m.serial = serial;
  m.model_json = axis.empty() ? std::string("{}") : R"({"axis":")" + axis + R"("})";
  auto ref = store.put_model(m);
  REQUIRE(ref.has_value());
  return ref->id;
}

NewVerdict verdict_of(std::int64_t run_id, std::int64_t model_id) {
  NewVerdict v;
  v.serial = "FOG-001";
  v.run_id = run_id;
  v.unit_index = 0;
  v.model_id = model_id;
  v.verdict = "pass";
  v.rule = "analysis";
  return v;
}

}  // namespace

TEST_CASE("store axis models: each axis has its current model (the model JSON's axis), a model without one is x", "[store][axes]") {
  CHECK(Store::current_schema_version() >= 14);
  TempDir tmp;
  auto store = open_ok(tmp / "a.db");
  const auto one = put_axis_model(store, "FOG-001", "");   // a one-axis unit's (version 1)
  const auto x = put_axis_model(store, "FOG-001", "x");    // version 2
  const auto y = put_axis_model(store, "FOG-001", "y");    // version 3
  const auto z = put_axis_model(store, "FOG-001", "z");    // version 4

  // Without an axis the current model is x's, not the latest stored (z's).
  auto cur = store.current_model("FOG-001");
  REQUIRE(cur.has_value());
  REQUIRE(cur->has_value());
  CHECK((*cur)->id == x);
  CHECK((*cur)->axis == "x");
  CHECK((*store.current_model("FOG-001", "y"))->id == y);
  CHECK((*store.current_model("FOG-001", "z"))->id == z);
  CHECK((*store.current_model("FOG-001", "z"))->version == 4);  // versions count across the axes
  CHECK(store.get_model(one)->axis.empty());
  CHECK(store.list_models("FOG-001")->size() == 4);

  // A serial with only a one-axis model: that is its x; it has no y.
  put_axis_model(store, "FOG-002", "");
  CHECK((*store.current_model("FOG-002", "x"))->axis.empty());
  CHECK_FALSE(store.current_model("FOG-002", "y")->has_value());

  auto bad_axis = store.current_model("FOG-001", "w");
  REQUIRE_FALSE(bad_axis.has_value());
  CHECK(bad_axis.error().code == StoreErrc::invalid_argument);
  NewModel w;
  w.serial = "FOG-001";
  w.model_json = R"({"axis":"w"})";
  auto refused = store.put_model(w);
  REQUIRE_FALSE(refused.has_value());
  CHECK(refused.error().code == StoreErrc::invalid_argument);
  CHECK_THAT(refused.error().message, Contains("model_json's axis"));
}

TEST_CASE("store axis models: a three-axis verdict keeps each axis' evidence, a one-axis verdict none", "[store][axes]") {
  TempDir tmp;
  auto store = open_ok(tmp / "a.db");
  const auto run = store.create_run(two_unit_run()).value();
  const auto x = put_axis_model(store, "FOG-001", "x");

  NewVerdict one = verdict_of(run, x);
  auto id1 = store.put_verdict(one);
  REQUIRE(id1.has_value());
  CHECK(store.latest_verdict("FOG-001")->value().axes_json.empty());
  Raw raw(tmp / "a.db");
  CHECK(raw.integer("SELECT count(*) FROM verdicts WHERE axes_json IS NULL") == 1);

  NewVerdict three = verdict_of(run, x);
  three.verdict = "fail";
  three.axes_json = R"([{"axis":"x","verdict":"pass"},{"axis":"y","verdict":"fail"},{"axis":"z","verdict":"pass"}])";
  auto id3 = store.put_verdict(three);
  REQUIRE(id3.has_value());
  CHECK(*id3 != *id1);  // not the same decision as the one-axis one: other evidence
  const auto latest = store.latest_verdict("FOG-001")->value();
  CHECK(latest.verdict == "fail");
  CHECK(latest.axes_json == three.axes_json);
  CHECK(store.put_verdict(three).value() == *id3);  // the same decision again is not written twice

  NewVerdict bad = verdict_of(run, x);
  bad.axes_json = R"({"axis":"x"})";
  auto refused = store.put_verdict(bad);
  REQUIRE_FALSE(refused.has_value());
  CHECK_THAT(refused.error().message, Contains("axes_json is not a JSON array"));
}

TEST_CASE("store axis models: a version 13 file upgrades to 14, its models and verdicts one-axis", "[store][axes][schema]") {
  TempDir tmp;
  const auto path = tmp / "old.db";
  std::int64_t model = 0;
  {
    auto store = open_ok(path);
    const auto run = store.create_run(two_unit_run()).value();
    model = put_axis_model(store, "FOG-001", "");
    REQUIRE(store.put_verdict(verdict_of(run, model)).has_value());
  }
  {
    // Back to what version 13 had: no axis on models, no axes_json on verdicts (nor version
    // 15's per-axis thermistors).
    Raw raw(path);
    raw.exec("DROP VIEW sample_view");
    for (const char* c : {"t1_y_c", "t2_y_c", "t1_z_c", "t2_z_c"}) raw.exec(std::string("ALTER TABLE samples DROP COLUMN ") + c);
    raw.exec("CREATE VIEW sample_view AS SELECT * FROM samples");
    raw.exec("DROP INDEX models_serial_axis");
    raw.exec("ALTER TABLE models DROP COLUMN axis");
    raw.exec("ALTER TABLE verdicts DROP COLUMN axes_json");
    raw.exec("PRAGMA user_version = 13");
  }
  auto store = open_ok(path);
  {
    Raw raw(path);
    CHECK(raw.integer("PRAGMA user_version") == Store::current_schema_version());
    CHECK(raw.integer("SELECT count(*) FROM models WHERE axis IS NULL") == 1);
  }
  auto cur = store.current_model("FOG-001");
  REQUIRE(cur.has_value());
  REQUIRE(cur->has_value());
  CHECK((*cur)->id == model);
  CHECK((*cur)->axis.empty());
  CHECK_FALSE(store.current_model("FOG-001", "y")->has_value());
  auto v = store.latest_verdict("FOG-001");
  REQUIRE(v.has_value());
  REQUIRE(v->has_value());
  CHECK((*v)->axes_json.empty());
  // The upgraded file takes a three-axis unit's models from now on.
  const auto y = put_axis_model(store, "FOG-001", "y");
  CHECK((*store.current_model("FOG-001", "y"))->id == y);
  CHECK((*store.current_model("FOG-001"))->id == model);
}
