// The plan runner driven alone (issue 26, point 3): a fake RunControl stands for the station
// and a real in-memory store holds the plan and its runs, so the test plays the station's part
// (a run completes, its analysis notes arrive) and asserts what the runner asked of it and the
// progress it saved. No daemon, no ticks of a real station, no time.
#include <catch2/catch.hpp>

#include <optional>
#include <set>
#include <string>
#include <vector>

#include "fixture.hpp"
#include "fogbench/daemon/plan_runner.hpp"
#include "fogbench/daemon/run_control.hpp"
#include "fogbench/profiles/profile.hpp"
#include "fogbench/storage/plans.hpp"

using namespace fogbench;
using namespace fogbench::daemon;
using nlohmann::json;

namespace {

struct FakeRuns final : RunControl {
  explicit FakeRuns(storage::Store& s) : store(s), units(test::golden_config().drivers.units) {}

  storage::Store& store;
  std::vector<drivers::UnitConfig> units;
  std::optional<std::int64_t> active;
  std::vector<std::string> started;  // the profile of each start_run_in_slots
  std::vector<std::vector<std::string>> started_units;
  std::vector<std::string> aborted;  // the reason of each abort_run
  std::set<std::int64_t> skipped, submitted;
  std::vector<std::int64_t> reanalysed;
  std::vector<std::string> decided;  // serials

  ApiResult<profiles::Profile> load_profile(const std::string& name, std::string*) const override {
    auto p = profiles::parse_profile("setpoint 20 C\nhold 3 min\n", name + ".profile");
    if (!p) return api_error(ErrorCode::not_found, "profile " + name);
    return std::move(*p);
  }
  const std::vector<drivers::UnitConfig>& bench_units() const override { return units; }
  std::optional<std::int64_t> active_run_id() const override { return active; }
  json status() const override { return json::object(); }
  ApiResult<std::int64_t> start_run_in_slots(const std::string& profile_name, const std::vector<SlotUnit>& us,
                                             storage::Purpose purpose, const json&, const OperatorId&) override {
    storage::NewRun nr;
    nr.profile_name = profile_name;
    nr.profile_text = "setpoint 20 C\nhold 3 min\n";
    nr.purpose = purpose;
    std::vector<std::string> serials;
    for (const auto& u : us) serials.push_back(u.serial);
    nr.unit_serials = serials;
    auto id = store.create_run(nr);
    REQUIRE(id);
    started.push_back(profile_name);
    started_units.push_back(serials);
    active = *id;
    return *id;
  }
  void resume_run_async(std::int64_t run_id, double, const json&, JobOrigin, ResumeDone done) override { done(run_id); }
  std::optional<std::int64_t> resuming_run_id() const override { return std::nullopt; }
  ApiResult<std::int64_t> abort_run(const std::string& reason, const json&) override {
    REQUIRE(active);
    aborted.push_back(reason);
    REQUIRE(store.set_run_state(*active, storage::RunState::aborted, reason));
    const auto id = *active;
    active.reset();
    return id;
  }
  void skip_analysis(std::int64_t run_id) override { skipped.insert(run_id); }
  bool analysing(std::int64_t run_id) const override { return submitted.contains(run_id); }
  void analyse_units(std::int64_t run_id, storage::Purpose, const std::vector<std::string>&,
                     const std::vector<int>&) override {
    reanalysed.push_back(run_id);
    submitted.insert(run_id);
  }
  ApiResult<std::string> decide(const storage::NewVerdict& v, bool) override {
    decided.push_back(v.serial);
    return api_error(ErrorCode::not_found, "no model");
  }

  // The station's part: the active run completes and its analysis is submitted (held: no note yet).
  void complete_active() {
    REQUIRE(active);
    REQUIRE(store.set_run_state(*active, storage::RunState::completed, "done"));
    submitted.insert(*active);
    active.reset();
  }
};

json progress_of(storage::Store& store, std::int64_t plan_id) {
  auto rec = store.get_plan(plan_id);
  REQUIRE(rec);
  return json::parse(rec->progress_json);
}

}  // namespace

TEST_CASE("plan runner with a fake RunControl: first run started in slots, waiting=analysis saved, judged, next run, abort") {
  auto store = test::memory_store();
  FakeRuns runs(store);
  PlanRunner runner(runs, store);

  auto started = runner.start("plan fake\nstep pfit fit\nstep pshort soak\n", "t.plan", {"FOG-0001", "FOG-0002"},
                              PlanTrace{}, json{{"cmd", "plan.start"}});
  REQUIRE(started);
  const auto plan_id = (*started)["plan_id"].get<std::int64_t>();
  CHECK(progress_of(store, plan_id)["waiting"] == "start");
  CHECK(runs.started.empty());

  // The first tick starts step 1's run in the units' slots.
  runner.after_tick(1.0, 1000.0);
  REQUIRE(runs.started == std::vector<std::string>{"pfit"});
  CHECK(runs.started_units[0] == std::vector<std::string>{"FOG-0001", "FOG-0002"});
  const auto run1 = *runs.active;
  CHECK(runs.skipped.empty());  // a fit step is analysed
  {
    auto p = progress_of(store, plan_id);
    CHECK(p["waiting"] == "run");
    CHECK(p["run_id"] == run1);
  }
  runner.after_tick(2.0, 1001.0);  // its run active: nothing changes
  CHECK(runs.started.size() == 1);

  // The run completes; its analysis is submitted but not stored (held, or on the worker): the
  // stored progress says the plan waits for the analysis (commit ca48841), and nothing is
  // analysed a second time.
  runs.complete_active();
  runner.after_tick(3.0, 1002.0);
  {
    auto p = progress_of(store, plan_id);
    CHECK(p["waiting"] == "analysis");
    CHECK(p["run_id"] == run1);
  }
  CHECK(runs.reanalysed.empty());
  CHECK(runs.started.size() == 1);
  auto status = runner.status(plan_id);
  REQUIRE(status);
  CHECK((*status)["progress"]["waiting"] == "analysis");

  // The analysis notes arrive: the units are judged and step 2's run (a soak: not analysed) starts.
  for (int u = 0; u < 2; ++u)
    REQUIRE(store.add_event(run1, storage::EventKind::note,
                            json{{"analysis", "fit"}, {"unit", u}, {"serial", u == 0 ? "FOG-0001" : "FOG-0002"},
                                 {"ok", true}}
                                .dump()));
  runner.after_tick(4.0, 1003.0);
  REQUIRE(runs.started == std::vector<std::string>{"pfit", "pshort"});
  const auto run2 = *runs.active;
  CHECK(run2 != run1);
  CHECK(runs.skipped == std::set<std::int64_t>{run2});
  {
    auto p = progress_of(store, plan_id);
    CHECK(p["step"] == 1);
    CHECK(p["waiting"] == "run");
    CHECK(p["run_id"] == run2);
    CHECK(p["runs"].size() == 2);
    for (const auto& u : p["units"]) CHECK(u["active"] == true);
  }
  CHECK(runs.decided.empty());

  // plan.abort: the plan's active run is aborted through RunControl, the plan ends aborted.
  auto ab = runner.abort("operator stop", json{{"cmd", "plan.abort"}});
  REQUIRE(ab);
  REQUIRE(runs.aborted.size() == 1);
  CHECK(runs.aborted[0].find("plan " + std::to_string(plan_id)) != std::string::npos);
  CHECK_FALSE(runs.active);
  auto rec = store.get_plan(plan_id);
  REQUIRE(rec);
  CHECK(rec->state == "aborted");
  auto p = json::parse(rec->progress_json);
  CHECK(p["waiting"].is_null());
  for (const auto& u : p["units"]) CHECK(u["verdict"] == "incomplete");
  CHECK_FALSE(runner.running_plan_id());
  runner.after_tick(5.0, 1004.0);  // nothing more starts
  CHECK(runs.started.size() == 2);
}

TEST_CASE("plan runner with a fake RunControl: a completed run nobody analyses is analysed again, once, and the plan waits") {
  auto store = test::memory_store();
  FakeRuns runs(store);
  PlanRunner runner(runs, store);
  auto started = runner.start("plan fake\nstep pfit fit\n", "t.plan", {"FOG-0001"}, PlanTrace{}, json::object());
  REQUIRE(started);
  const auto plan_id = (*started)["plan_id"].get<std::int64_t>();
  runner.after_tick(1.0, 1000.0);
  REQUIRE(runs.active);
  const auto run1 = *runs.active;
  REQUIRE(store.set_run_state(run1, storage::RunState::completed, "done"));
  runs.active.reset();  // completed by a process that was killed before submitting its analysis
  runner.after_tick(2.0, 1001.0);
  CHECK(runs.reanalysed == std::vector<std::int64_t>{run1});
  CHECK(progress_of(store, plan_id)["waiting"] == "analysis");
  runner.after_tick(3.0, 1002.0);
  CHECK(runs.reanalysed.size() == 1);
}

TEST_CASE("plan runner: plan.status without an id gives the running plan, else the last one that ran, never one removed from the queue") {
  auto store = test::memory_store();
  FakeRuns runs(store);
  PlanRunner runner(runs, store);
  {
    auto none = runner.status(std::nullopt);
    REQUIRE_FALSE(none);
    CHECK(none.error().code == ErrorCode::not_found);
  }
  auto started = runner.start("plan first\nstep pshort soak\n", "t.plan", {"FOG-0001"}, PlanTrace{}, json{{"cmd", "plan.start"}});
  REQUIRE(started);
  const auto first = (*started)["plan_id"].get<std::int64_t>();
  runner.after_tick(1.0, 1000.0);
  REQUIRE(runs.active);
  auto queued = runner.queue_add("plan second\nstep pshort soak\n", "q.plan", {"FOG-0002"}, PlanTrace{}, json{{"cmd", "queue.add"}});
  REQUIRE(queued);
  const auto second = (*queued)["plan_id"].get<std::int64_t>();
  REQUIRE(second > first);
  {
    auto s = runner.status(std::nullopt);
    REQUIRE(s);
    CHECK((*s)["plan_id"] == first);  // the running one
  }
  REQUIRE(runner.abort("stop", json{{"cmd", "plan.abort"}}));
  REQUIRE(runner.queue_remove(second, json{{"cmd", "queue.remove"}}));
  auto removed = store.get_plan(second);
  REQUIRE(removed);
  CHECK(removed->state != "queued");  // it ended without starting
  CHECK_FALSE(removed->started_at);
  auto s = runner.status(std::nullopt);
  REQUIRE(s);
  CHECK((*s)["plan_id"] == first);  // the last one that ran, not the removed one
  auto by_id = runner.status(second);  // asked by its id, the removed plan is still shown
  REQUIRE(by_id);
  CHECK((*by_id)["plan_id"] == second);
}

TEST_CASE("plan commands: plan.abort's reason is checked as every stored text, naming the field, the plan left running") {
  // The reason is stored with the plan and its run (issue 27, point 8): a control character or
  // one beyond storage::kMaxReasonBytes is refused before anything is aborted.
  auto store = test::memory_store();
  FakeRuns runs(store);
  PlanRunner runner(runs, store);
  auto started = runner.start("plan first\nstep pshort soak\n", "t.plan", {"FOG-0001"}, PlanTrace{}, json{{"cmd", "plan.start"}});
  REQUIRE(started);
  runner.after_tick(1.0, 1000.0);
  REQUIRE(runs.active);
  auto refused = [&](const std::string& reason) {
    auto r = plan_abort(&runner, "plan.abort", json{{"cmd", "plan.abort"}, {"reason", reason}});
    REQUIRE_FALSE(r);
    CHECK(r.error().code == ErrorCode::bad_request);
    return r.error().message;
  };
  CHECK(refused("done\x1b]0;owned\x07") == "reason: control character 0x1B at byte 5");
  CHECK(refused(std::string(501, 'r')) == "reason: longer than 500 bytes (501)");
  CHECK(runs.aborted.empty());
  REQUIRE(runs.active);
  auto ok = plan_abort(&runner, "plan.abort", json{{"cmd", "plan.abort"}, {"reason", "line stop"}});
  REQUIRE(ok);
  REQUIRE(runs.aborted.size() == 1);
  CHECK_THAT(runs.aborted[0], Catch::Contains("line stop"));
}
