// Bench slots: the serial in each slot is given per run (run.start's `slots`), checked, stored
// with the run, shown by run.get and status, and a resumed run goes back to its slots. The golden
// configuration has slots A (FOG-0001 by default) and B (FOG-0002).
#include "fixture.hpp"

#include "fogbench/daemon/bench_slots.hpp"
#include "fogbench/daemon/handler.hpp"
#include "fogbench/daemon/plan_runner.hpp"
#include "fogbench/storage/plans.hpp"

using namespace fogbench;
using namespace fogbench::daemon;
using namespace fogbench::daemon::test;
using nlohmann::json;

namespace {

const std::vector<drivers::UnitConfig>& slots() {
  static const DaemonConfig c = golden_config();
  return c.drivers.units;
}

// The refusal of slot_units for this request: its code and message.
std::string refusal(const json& req) {
  auto r = slot_units(req, slots(), true);
  REQUIRE_FALSE(r.has_value());
  return std::string(protocol::to_string(r.error().code)) + ": " + r.error().message;
}

struct Rig {
  storage::Store store = memory_store();
  Station station{golden_config(), store};
  Handler handler{station};
  SessionState session;
  json send(const json& req) { return handler.handle_line(req.dump(), session); }
  std::string code(const json& req) {
    json r = send(req);
    REQUIRE(r["type"] == "reply");
    return r.contains("error") ? r["error"]["code"].get<std::string>() : "ok";
  }
};

json start(const json& slots_json) {
  return {{"id", 1}, {"cmd", "run.start"}, {"profile", "short"}, {"slots", slots_json}};
}

}  // namespace

TEST_CASE("bench slots: the configured slots are named by index, their serials defaults") {
  REQUIRE(slots().size() == 2);
  CHECK(slots()[0].slot == "A");
  CHECK(slots()[1].slot == "B");
  CHECK(slots()[1].serial == "FOG-0002");
}

TEST_CASE("bench slots: serials per slot, units by default serial, in the configuration's order") {
  auto r = slot_units({{"slots", {{"B", "FOG-0042"}}}}, slots(), true);
  REQUIRE(r.has_value());
  REQUIRE(r->size() == 1);
  CHECK((*r)[0].config_index == 1);
  CHECK((*r)[0].serial == "FOG-0042");

  // `units` first, as given (the old way), then `slots` in slot order whatever the JSON's.
  r = slot_units({{"units", {"FOG-0002"}}, {"slots", {{"A", "FOG-0042"}}}}, slots(), true);
  REQUIRE(r.has_value());
  REQUIRE(r->size() == 2);
  CHECK((*r)[0].config_index == 1);
  CHECK((*r)[0].serial == "FOG-0002");
  CHECK((*r)[1].config_index == 0);
  CHECK((*r)[1].serial == "FOG-0042");
  CHECK(serials_of(*r) == std::vector<std::string>{"FOG-0002", "FOG-0042"});

  // A slot not named takes no part, though it has a default serial.
  r = slot_units({{"slots", {{"A", "FOG-0001"}}}}, slots(), true);
  REQUIRE(r.has_value());
  CHECK(r->size() == 1);

  // Neither: refused when required, else no units (plan.validate).
  CHECK(refusal(json::object()) == "bad_request: units: missing (give units or slots)");
  auto none = slot_units(json::object(), slots(), false);
  REQUIRE(none.has_value());
  CHECK(none->empty());
}

TEST_CASE("bench slots: each bad slot or serial is refused naming the field") {
  CHECK(refusal({{"slots", "A=FOG-0042"}}) ==
        R"(bad_request: slots: expected an object {slot: serial}, e.g. {"A": "FOG-0042"})");
  CHECK(refusal({{"slots", {{"C", "FOG-0042"}}}}) == "bad_request: slots.C: no such slot on this bench (slots: A, B)");
  CHECK(refusal({{"slots", {{"A", ""}}}}) == "bad_request: slots.A: empty serial");
  CHECK(refusal({{"slots", {{"A", 42}}}}) == "bad_request: slots.A: expected a serial (a string)");
  CHECK(refusal({{"slots", {{"A", "FOG\n0042"}}}}) == "bad_request: slots.A: control character 0x0A at byte 4");
  // A barcode scanner's Enter ends the input; a stray one in the serial is refused, not stored.
  CHECK(refusal({{"slots", {{"A", "FOG-0042\r"}}}}) == "bad_request: slots.A: control character 0x0D at byte 9");
  CHECK(refusal({{"slots", {{"A", std::string(65, 'F')}}}}) == "bad_request: slots.A: longer than 64 bytes (65)");
  CHECK(refusal({{"slots", json::object()}}) == "bad_request: slots: expected at least one slot");
  // One serial in two slots, one slot named twice (by its default serial and by `slots`).
  CHECK(refusal({{"slots", {{"A", "FOG-0042"}, {"B", "FOG-0042"}}}}) ==
        "bad_request: slots.B: FOG-0042 is already in slots.A");
  CHECK(refusal({{"units", {"FOG-0002"}}, {"slots", {{"B", "FOG-0042"}}}}) ==
        "bad_request: slots.B: slot B is already given by units[0]");
  CHECK(refusal({{"units", {"FOG-0001", "FOG-0001"}}}) == "bad_request: units: FOG-0001 given twice");
  CHECK(refusal({{"units", {""}}}) == "bad_request: units[0]: empty serial");
  // A serial that is no slot's default: unknown_serial, saying how to give its slot.
  CHECK(refusal({{"units", {"FOG-0042"}}}) ==
        R"(unknown_serial: unit FOG-0042: not the default serial of any slot on this bench (give its slot: slots {"A": "FOG-0042"}, fogctl --slot A=FOG-0042))");
}

TEST_CASE("bench slots: run.start refuses a bad slot before anything is stored") {
  Rig r;
  CHECK(r.code(start({{"C", "FOG-0042"}})) == "bad_request");
  CHECK(r.code(start({{"A", ""}})) == "bad_request");
  CHECK(r.code(start({{"A", "FOG\t1"}})) == "bad_request");
  CHECK(r.code(start({{"A", std::string(65, 'F')}})) == "bad_request");
  CHECK(r.code(start({{"A", "FOG-0042"}, {"B", "FOG-0042"}})) == "bad_request");
  // A slot twice in one `slots` object: a key twice, refused as the whole request is.
  json dup = r.handler.handle_line(
      R"({"id":1,"cmd":"run.start","profile":"short","slots":{"A":"FOG-0042","A":"FOG-0043"}})", r.session);
  CHECK(dup["error"]["code"] == "bad_json");
  CHECK(r.code({{"id", 1}, {"cmd", "run.start"}, {"profile", "short"}, {"units", {"FOG-0042"}}}) == "unknown_serial");
  // A verify run needs the serial's model, as before.
  CHECK(r.code({{"id", 1}, {"cmd", "run.start"}, {"profile", "short"}, {"purpose", "verify"},
                {"slots", {{"A", "FOG-0042"}}}}) == "unknown_serial");
  CHECK(r.store.list_runs()->empty());
  CHECK(r.station.active_run_id() == std::nullopt);
}

TEST_CASE("bench slots: the serial given is the run's, in run.get and status, and changes between runs") {
  Rig r;
  json ok = r.send(start({{"B", "FOG-0042"}}));
  REQUIRE(ok.contains("result"));
  const auto first = ok["result"]["run_id"].get<std::int64_t>();
  json s = r.send({{"id", 2}, {"cmd", "status"}})["result"];
  CHECK(s["run"]["units"] == json{"FOG-0042"});
  CHECK(s["run"]["slots"] == json{"B"});
  REQUIRE(s["units"].size() == 2);
  CHECK(s["units"][0]["slot"] == "A");
  CHECK(s["units"][0]["serial"] == "FOG-0001");  // not in the run: the configured default
  CHECK(s["units"][1]["slot"] == "B");
  CHECK(s["units"][1]["serial"] == "FOG-0042");
  json g = r.send({{"id", 3}, {"cmd", "run.get"}, {"run_id", first}})["result"];
  CHECK(g["run"]["units"] == json{"FOG-0042"});
  CHECK(g["run"]["slots"] == json{"B"});
  CHECK(g["identity"]["units"][0]["serial"] == "FOG-0042");
  REQUIRE(r.code({{"id", 4}, {"cmd", "run.abort"}}) == "ok");
  (void)r.station.tick(0.0, SyntheticBench(2).step(20));

  // The next unit in the same slot: nothing to configure, nothing restarted.
  ok = r.send(start({{"B", "FOG-0043"}}));
  REQUIRE(ok.contains("result"));
  const auto second = ok["result"]["run_id"].get<std::int64_t>();
  CHECK(second != first);
  g = r.send({{"id", 5}, {"cmd", "run.get"}, {"run_id", second}})["result"];
  CHECK(g["run"]["units"] == json{"FOG-0043"});
  CHECK(g["run"]["slots"] == json{"B"});
  CHECK(r.store.get_run(first)->run.units[0].serial == "FOG-0042");
  CHECK(r.store.get_run(first)->run.units[0].slot == std::optional<std::string>("B"));
}

TEST_CASE("bench slots: a resumed run reads the slot it was stored in, not the default serial's") {
  auto store = memory_store();
  SyntheticBench bench(2);
  std::int64_t id = 0;
  {
    Station st(golden_config(), store);  // crashes: never shut down
    auto started = st.start_run_in_slots("short", {{1, "FOG-0042"}}, storage::Purpose::fit, {{"cmd", "run.start"}}, OperatorId{});
    REQUIRE(started.has_value());
    id = *started;
    for (int i = 0; i < 5; ++i) st.tick(i, bench.step(20));
  }
  Station restarted(golden_config(), store);
  REQUIRE(restarted.recover().has_value());
  REQUIRE(store.get_run(id)->run.state == storage::RunState::interrupted);
  auto resumed = restarted.resume_run(id, 0.0, {{"cmd", "run.resume"}});
  REQUIRE(resumed.has_value());
  json s = restarted.status();
  CHECK(s["run"]["units"] == json{"FOG-0042"});
  CHECK(s["run"]["slots"] == json{"B"});
  CHECK(s["units"][1]["serial"] == "FOG-0042");
}

TEST_CASE("bench slots: plan.start and queue.add take slots, and the plan's runs use them") {
  auto store = memory_store();
  Station st(golden_config(), store);
  PlanRunner runner(st, st.store());
  const std::string text = "plan one-step\nstep short fit\n";
  json req = {{"cmd", "plan.start"}, {"text", text}, {"source", "one.plan"}, {"slots", {{"C", "FOG-0042"}}}};
  auto bad = plan_start(&runner, "plan.start", req, "");
  REQUIRE_FALSE(bad.has_value());
  CHECK(bad.error().message == "slots.C: no such slot on this bench (slots: A, B)");
  req["slots"] = {{"B", ""}};
  bad = queue_add(&runner, "queue.add", req, "");
  REQUIRE_FALSE(bad.has_value());
  CHECK(bad.error().message == "slots.B: empty serial");
  req["slots"] = {{"B", "FOG-0042"}};
  bad = plan_validate(&runner, "plan.validate", {{"text", text}, {"slots", {{"A", "FOG-0042"}, {"B", "FOG-0042"}}}});
  REQUIRE_FALSE(bad.has_value());
  CHECK(bad.error().message == "slots.B: FOG-0042 is already in slots.A");
  CHECK(store.list_plans().value().empty());

  auto ok = plan_start(&runner, "plan.start", req, "");
  REQUIRE(ok.has_value());
  const auto plan_id = (*ok)["plan_id"].get<std::int64_t>();
  CHECK(store.get_plan(plan_id).value().slots == std::map<std::string, std::string>{{"FOG-0042", "B"}});
  CHECK(runner.status(plan_id).value()["slots"] == json{{"FOG-0042", "B"}});
  runner.after_tick(0.0, 0.0);  // the plan's first step starts its run
  auto run = st.active_run_id();
  REQUIRE(run.has_value());
  const auto units = store.get_run(*run).value().run.units;
  REQUIRE(units.size() == 1);
  CHECK(units[0].serial == "FOG-0042");
  CHECK(units[0].slot == std::optional<std::string>("B"));
}

TEST_CASE("bench slots: a reload may not rename or remove the slot of a unit of a plan not yet done, and may change default serials") {
  auto store = memory_store();
  Station st(golden_config(), store);
  PlanRunner runner(st, st.store());
  const std::string text = "plan one-step\nstep short fit\n";
  // A running plan with FOG-0042 given slot B, a queued one with FOG-0001 in its default slot A
  // (a plan stores every unit's slot by name when it is accepted).
  json req = {{"cmd", "plan.start"}, {"text", text}, {"source", "one.plan"}, {"slots", {{"B", "FOG-0042"}}}};
  REQUIRE(plan_start(&runner, "plan.start", req, "").has_value());
  REQUIRE(queue_add(&runner, "queue.add", {{"cmd", "queue.add"}, {"text", text}, {"source", "two.plan"},
                                           {"units", {"FOG-0001"}}},
                    "")
              .has_value());
  CHECK_FALSE(runner.slot_change_refusal(st.config().drivers.units).has_value());  // the same file

  auto next = st.config().drivers.units;
  next[1].slot = "RIGHT";  // the running plan named slot B: it would find no slot at its next step
  auto why = runner.slot_change_refusal(next);
  REQUIRE(why.has_value());
  CHECK_THAT(*why, Catch::StartsWith("drivers.units: running plan 1 (one-step) has FOG-0042 in slot B (position 2); "
                                     "this file would place it in no slot at the plan's next step"));

  next = st.config().drivers.units;
  next[0].slot = "LEFT";  // the queued plan's FOG-0001 was placed in A when it was queued
  why = runner.slot_change_refusal(next);
  REQUIRE(why.has_value());
  CHECK_THAT(*why, Catch::StartsWith("drivers.units: queued plan 2 (one-step) has FOG-0001 in slot A (position 1)"));

  next = st.config().drivers.units;
  next[0].serial = "FOG-0005";  // a new default serial: the plans keep their slots by name
  next[1].serial = "FOG-0006";
  CHECK_FALSE(runner.slot_change_refusal(next).has_value());
}
