// A plan whose daemon is killed (SIGKILL) between a step's run completing and the storage of its
// analysis (docs/plans.md, "A restart"): the restarted daemon analyses the run again from its
// stored samples and the plan advances. The kill is placed deterministically by the test-only
// FOGBENCH_TEST_KILL_BEFORE_ANALYSIS=1 (the daemon raises SIGKILL where it would submit the
// analysis); the restart is the real one, on the same store.
#include "../daemon/live_bench.hpp"

#include <fstream>

#include "fogbench/storage/plans.hpp"
#include "fogbench/storage/runs.hpp"
#include "fogbench/storage/store.hpp"

using namespace fogbench::daemon::test;
using namespace fogbench::daemon::test::live;

namespace {

int analysis_notes(const fogbench::storage::RunDetail& d, int unit) {
  int n = 0;
  for (const auto& e : d.events) {
    if (e.kind != fogbench::storage::EventKind::note) continue;
    json j = json::parse(e.detail_json, nullptr, false);
    if (j.is_object() && j.contains("analysis") && j.value("unit", -1) == unit) ++n;
  }
  return n;
}

}  // namespace

TEST_CASE("plan e2e: SIGKILL between a fit run's end and its analysis, the restarted daemon analyses it and the plan completes") {
  require_sim();
  LiveBench bench(100.0, json::object(), true);
  INFO("test dir " << bench.dir);
  std::ofstream(bench.dir / "profiles" / "pfit.profile")
      << "setpoint 20 C\nhold 10 min\nramp to 30 C at 1 C/min\nhold 15 min\nramp to 20 C at 1 C/min\nhold 15 min\n";
  std::ofstream(bench.dir / "profiles" / "pshort.profile") << "setpoint 20 C\nhold 3 min\n";
  // The daemon again, with the kill armed.
  bench.daemon->kill_now();
  bench.daemon_prefix = {"/usr/bin/env", "FOGBENCH_TEST_KILL_BEFORE_ANALYSIS=1"};
  bench.start_daemon();
  std::int64_t plan_id = 0;
  {
    LineClient c(bench.socket());
    REQUIRE(c.ok());
    auto s = c.call({{"cmd", "plan.start"},
                     {"text", "plan killed-analysis\nstep pfit fit\nstep pshort soak\n"},
                     {"source", "t.plan"},
                     {"units", {"SIM-0001", "SIM-0002"}}});
    INFO(s.dump());
    REQUIRE(code_of(s) == "ok");
    plan_id = s["result"]["plan_id"].get<std::int64_t>();
  }
  // The daemon dies by itself when the fit run completes (generous: the run is 36 s at K = 100).
  // The wait stays well inside the test's 600 s CTest timeout, so that a daemon that never gets
  // there fails here with its log named rather than being cut off without a word.
  bench.daemon->wait(400s);
  INFO("fogbenchd log in " << (bench.dir / "fogbenchd.log") << " (FOGBENCH_KEEP_TEST_DIRS=1 keeps it)");
  REQUIRE_FALSE(bench.daemon->running());
  std::int64_t run_id = 0;
  {
    auto st = fogbench::storage::Store::open(bench.dir / "fogbench.db");
    REQUIRE(st);
    auto plan = st->get_plan(plan_id);
    REQUIRE(plan);
    INFO(plan->progress_json);
    REQUIRE(plan->state == "running");
    json progress = json::parse(plan->progress_json);
    REQUIRE(progress["step"] == 0);
    REQUIRE(progress["run_id"].is_number());
    run_id = progress["run_id"].get<std::int64_t>();
    auto d = st->get_run(run_id);
    REQUIRE(d);
    // Exactly the window of the issue: the run completed, its analysis never stored.
    REQUIRE(d->run.state == fogbench::storage::RunState::completed);
    CHECK(analysis_notes(*d, 0) == 0);
    CHECK(analysis_notes(*d, 1) == 0);
  }
  bench.daemon_prefix.clear();
  bench.start_daemon();
  LineClient c(bench.socket());
  REQUIRE(c.ok());
  const auto deadline = SteadyClock::now() + 300s;
  json done;
  while (SteadyClock::now() < deadline) {
    done = c.call({{"cmd", "plan.status"}, {"plan_id", plan_id}});
    if (done.is_object() && done.contains("result") && done["result"]["state"] != "running") break;
    std::this_thread::sleep_for(200ms);
  }
  INFO(done.dump(1));
  REQUIRE(done["result"]["state"] == "completed");
  const auto& runs = done["result"]["progress"]["runs"];
  REQUIRE(runs.size() == 2);
  CHECK(runs[0]["run_id"] == run_id);  // the fit step was not run again: its run was analysed
  for (const auto& u : done["result"]["progress"]["units"]) {
    INFO(u.dump());
    CHECK(u["active"] == true);
  }
  auto st = fogbench::storage::Store::open(bench.dir / "fogbench.db");
  REQUIRE(st);
  auto d = st->get_run(run_id);
  REQUIRE(d);
  for (int unit : {0, 1}) {
    INFO("unit " << unit);
    CHECK(analysis_notes(*d, unit) == 1);  // once each: no unit analysed twice
  }
  bool model_stored = false;
  for (const auto& e : d->events) {
    json j = json::parse(e.detail_json, nullptr, false);
    if (j.is_object() && j.contains("analysis") && j.value("ok", false) && j.contains("model_id")) model_stored = true;
  }
  CHECK(model_stored);
  auto events = st->plan_events(plan_id);
  REQUIRE(events);
  bool reanalysed = false;
  for (const auto& e : *events)
    if (e.kind == "plan.analysis") reanalysed = json::parse(e.detail_json)["run_id"] == run_id;
  CHECK(reanalysed);
}
