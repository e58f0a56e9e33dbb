// The store's qualification plans (schema versions 6 and 8, docs/plans.md): a plan's states and
// progress, the queue's order through set_queue, a removal, and the audit trail.
#include <catch2/catch.hpp>

#include <nlohmann/json.hpp>

#include "fogbench/storage/errors.hpp"
#include "fogbench/storage/plans.hpp"
#include "fogbench/storage/runs.hpp"
#include "fogbench/storage/store.hpp"

using namespace fogbench::storage;

namespace {
Store memory() {
  auto s = Store::open(":memory:");
  REQUIRE(s.has_value());
  return std::move(*s);
}
NewPlan plan(const std::string& name, const std::string& state = "queued") {
  return NewPlan{name, name + ".plan", "step exp1 fit\n", {"SIM-0001", "SIM-0002"}, state};
}
std::vector<std::int64_t> queued(Store& s) {
  std::vector<std::int64_t> ids;
  const auto plans = s.list_plans("queued");
  REQUIRE(plans.has_value());
  for (const auto& p : *plans) ids.push_back(p.id);
  return ids;
}
}  // namespace

TEST_CASE("store plans: queued plans keep their order, move and leave the queue, each change audited", "[store][plans]") {
  Store s = memory();
  const auto a = s.create_plan(plan("a"), "queue.add", R"({"cmd":"queue.add"})").value();
  const auto b = s.create_plan(plan("b"), "queue.add", "").value();
  const auto c = s.create_plan(plan("c"), "queue.add", "").value();
  CHECK(queued(s) == std::vector<std::int64_t>{a, b, c});
  auto rec = s.get_plan(a).value();
  CHECK(rec.units == std::vector<std::string>{"SIM-0001", "SIM-0002"});
  CHECK(rec.state == "queued");
  CHECK(rec.queue_pos == 1);
  CHECK_FALSE(rec.started_at.has_value());

  REQUIRE(s.set_queue({c, a, b}, std::nullopt, "queue.move", R"({"plan_id":3})").has_value());
  CHECK(queued(s) == std::vector<std::int64_t>{c, a, b});
  REQUIRE(s.set_queue({c, b}, a, "queue.remove", "").has_value());
  CHECK(queued(s) == std::vector<std::int64_t>{c, b});
  CHECK(s.get_plan(a).value().state == "aborted");
  CHECK(s.get_plan(a).value().reason == "removed from the queue");
  // A plan that is not queued cannot be put in order or removed; nothing changes.
  CHECK_FALSE(s.set_queue({c, b, a}, std::nullopt, "queue.move", "").has_value());
  CHECK_FALSE(s.set_queue({c}, a, "queue.remove", "").has_value());
  CHECK(queued(s) == std::vector<std::int64_t>{c, b});

  auto events = s.plan_events(std::nullopt).value();
  REQUIRE(events.size() == 5);
  CHECK(events[0].kind == "queue.add");
  CHECK(events[0].plan_id == a);
  CHECK(events[3].kind == "queue.move");
  CHECK(events[4].kind == "queue.remove");
  CHECK(events[4].plan_id == a);
  CHECK(s.plan_events(a).value().size() == 2);
}

TEST_CASE("store plans: a running plan's progress and its end are stamped", "[store][plans]") {
  Store s = memory();
  const auto id = s.create_plan(plan("run", "running"), "plan.start", "").value();
  auto rec = s.get_plan(id).value();
  CHECK(rec.state == "running");
  CHECK(rec.started_at.has_value());
  CHECK_FALSE(rec.queue_pos.has_value());
  REQUIRE(s.update_plan(id, "running", "", R"({"step":1})").has_value());
  CHECK(nlohmann::json::parse(s.get_plan(id).value().progress_json)["step"] == 1);
  CHECK_FALSE(s.get_plan(id).value().ended_at.has_value());
  REQUIRE(s.update_plan(id, "completed", "", R"({"step":2})").has_value());
  rec = s.get_plan(id).value();
  CHECK(rec.state == "completed");
  CHECK(rec.ended_at.has_value());
  // Refused: progress that is not JSON, a state the schema does not know, a plan that is not.
  CHECK_FALSE(s.update_plan(id, "running", "", "{").has_value());
  CHECK_FALSE(s.update_plan(id, "sleeping", "", "{}").has_value());
  CHECK(s.get_plan(id).value().state == "completed");
  CHECK(s.update_plan(99, "running", "", "{}").error().code == StoreErrc::not_found);
  CHECK(s.get_plan(99).error().code == StoreErrc::not_found);
  CHECK_FALSE(s.create_plan(plan("x", "completed"), "plan.start", "").has_value());
}

TEST_CASE("store plans: a plan keeps its operator and its units' lots (schema version 8)", "[store][plans]") {
  Store s = memory();
  NewPlan p = plan("traced");
  p.operator_name = "alice";
  p.operator_source = "client";
  p.lots = {{"SIM-0001", "LOT-7"}};
  const auto id = s.create_plan(p, "queue.add", "").value();
  auto rec = s.get_plan(id).value();
  CHECK(rec.operator_name == "alice");
  CHECK(rec.operator_source == "client");
  CHECK(rec.lots == std::map<std::string, std::string>{{"SIM-0001", "LOT-7"}});
  // A plan given neither: nobody and no lot, as a plan stored before version 8 reads back.
  rec = s.get_plan(s.create_plan(plan("bare"), "queue.add", "").value()).value();
  CHECK(rec.operator_name.empty());
  CHECK(rec.operator_source == "none");
  CHECK(rec.lots.empty());
  // The schema refuses an operator source it does not know.
  p.operator_source = "guess";
  CHECK_FALSE(s.create_plan(p, "queue.add", "").has_value());
}

TEST_CASE("store plans and runs keep each unit's bench slot, none for those stored before", "[store][plans]") {
  Store s = memory();
  NewPlan p = plan("slotted");
  p.slots = {{"SIM-0001", "A"}, {"SIM-0002", "left-2"}};
  const auto id = s.create_plan(p, "queue.add", "").value();
  CHECK(s.get_plan(id).value().slots == p.slots);
  CHECK(s.get_plan(s.create_plan(plan("plain"), "queue.add", "").value()).value().slots.empty());

  NewRun r;
  r.profile_name = "exp1";
  r.unit_serials = {"FOG-0042", "FOG-0043"};
  r.unit_slots = {"B"};  // shorter: the second unit has none
  const auto run = s.create_run(r).value();
  const auto units = s.get_run(run).value().run.units;
  REQUIRE(units.size() == 2);
  CHECK(units[0].slot == std::optional<std::string>("B"));
  CHECK(units[1].slot == std::nullopt);
  // The column's bound: a slot name is 1..16 characters.
  r.unit_slots = {std::string(17, 'x'), "A"};
  CHECK_FALSE(s.create_run(r).has_value());
}
