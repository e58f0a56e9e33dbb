// The station without I/O: whole runs on a synthetic bench, the state machine and its audit
// trail, quality flags, and the automatic fit and verification.
#include "fixture.hpp"

#include "fogbench/model/firmware.hpp"
#include "fogbench/model/json.hpp"
#include "fogbench/storage/models.hpp"

using namespace fogbench;
using namespace fogbench::daemon;
using namespace fogbench::daemon::test;
using nlohmann::json;

namespace {
std::vector<std::string> event_kinds(storage::Store& s, std::int64_t run) {
  auto d = s.get_run(run);
  REQUIRE(d.has_value());
  std::vector<std::string> k;
  for (const auto& e : d->events) k.push_back(std::string(storage::to_string(e.kind)));
  return k;
}
std::vector<std::string> states(storage::Store& s, std::int64_t run) {
  auto d = s.get_run(run);
  REQUIRE(d.has_value());
  std::vector<std::string> out;
  for (const auto& e : d->events)
    if (e.kind == storage::EventKind::state) out.push_back(json::parse(e.detail_json).value("to", ""));
  return out;
}
}  // namespace

TEST_CASE("station: a fit run goes pending -> settling -> running -> completed and fits each unit") {
  auto store = memory_store();
  Station st(golden_config(), store, 1.0, [] { return std::string("2026-01-01T00:00:00Z"); });
  std::vector<json> published;
  st.set_publisher([&](const json& m) { published.push_back(m); });
  SyntheticBench bench(2);
  double clock_s = 100.0;  // the daemon has been up a while: run time starts at the run's start

  auto id = st.start_run("short", {"FOG-0001", "FOG-0002"}, storage::Purpose::fit, {{"cmd", "run.start"}});
  REQUIRE(id.has_value());
  CHECK(st.status()["run"]["state"] == "pending");
  const int ticks = run_to_end(st, bench, clock_s);

  // short.profile: 600 + 300 + 300 + 300 + 300 s; the tick at its end completes it.
  CHECK(ticks == 1801);
  auto d = store.get_run(*id);
  REQUIRE(d.has_value());
  CHECK(d->run.state == storage::RunState::completed);
  CHECK(states(store, *id) == std::vector<std::string>{"pending", "settling", "running", "completed"});
  CHECK(*store.count_samples(*id, 0) == ticks);
  CHECK(*store.count_samples(*id, 1) == ticks);
  auto rows = store.get_samples(*id, 0, 0, 2);
  REQUIRE(rows->size() == 2);
  CHECK(rows->at(0).t_s == 0.0);  // run time, not daemon time
  CHECK(rows->at(1).t_s == 1.0);
  CHECK(rows->at(0).flags == 0);

  // The synthetic drift is y = -8 - 2.7 T1' - 0.4 dT + noise(0.05): the fit recovers the
  // trend coefficients. Tolerance: the paper method smooths over 61 s and fits the lag, and a
  // 5 degC excursion gives a short lever arm, so 15% on beta1 and 0.25 deg/h on mu0.
  for (const char* serial : {"FOG-0001", "FOG-0002"}) {
    auto m = store.current_model(serial);
    REQUIRE(m.has_value());
    REQUIRE(m->has_value());
    CHECK((*m)->run_id == *id);
    CHECK(!(*m)->parent_id);
    auto model = model::model_from_text((*m)->model_json);
    REQUIRE(model.has_value());
    CHECK(model->mu0_dph == Approx(-8.0).margin(0.25));
    REQUIRE(model->terms.size() == 2);
    CHECK(model->terms[0].coef == Approx(-2.7).epsilon(0.15));
    CHECK(model->created_at == "2026-01-01T00:00:00Z");
  }
  // The setpoint went back to the safe one.
  CHECK(st.status()["setpoint_c"] == 20.0);
  CHECK(st.status()["run"].is_null());
  // Samples and the state events were pushed to subscribers.
  CHECK(std::count_if(published.begin(), published.end(), [](const json& m) { return m["type"] == "sample"; }) == 2 * ticks);

  SECTION("a verify run on the same bench passes; a second fit has the first as parent") {
    auto v = st.start_run("short", {"FOG-0001"}, storage::Purpose::verify, {{"cmd", "run.start"}});
    REQUIRE(v.has_value());
    run_to_end(st, bench, clock_s);
    auto vs = store.list_verifications(*v);
    REQUIRE(vs.has_value());
    REQUIRE(vs->size() == 1);
    CHECK(vs->at(0).pass);
    auto first = store.current_model("FOG-0001");

    auto f = st.start_run("short", {"FOG-0001"}, storage::Purpose::fit, {{"cmd", "run.start"}});
    REQUIRE(f.has_value());
    run_to_end(st, bench, clock_s);
    auto second = store.current_model("FOG-0001");
    REQUIRE((*second)->version == 2);
    CHECK((*second)->parent_id == (*first)->id);
  }
}

TEST_CASE("station: refusals leave the store untouched") {
  auto store = memory_store();
  Station st(golden_config(), store);
  const json cmd = {{"cmd", "run.start"}};
  auto code = [&](auto r) { return r ? std::string("ok") : std::string(to_string(r.error().code)); };
  CHECK(code(st.start_run("short", {"FOG-0001"}, storage::Purpose::verify, cmd)) == "unknown_serial");  // no model
  CHECK(code(st.start_run("short", {"FOG-9999"}, storage::Purpose::fit, cmd)) == "unknown_serial");
  CHECK(code(st.start_run("hot", {"FOG-0001"}, storage::Purpose::fit, cmd)) == "limits");
  CHECK(code(st.start_run("fast", {"FOG-0001"}, storage::Purpose::fit, cmd)) == "limits");
  CHECK(code(st.start_run("broken", {"FOG-0001"}, storage::Purpose::fit, cmd)) == "invalid_profile");
  CHECK(code(st.start_run("nosuch", {"FOG-0001"}, storage::Purpose::fit, cmd)) == "not_found");
  CHECK(code(st.start_run("../etc/passwd", {"FOG-0001"}, storage::Purpose::fit, cmd)) == "bad_request");
  CHECK(code(st.start_run("short", {}, storage::Purpose::fit, cmd)) == "bad_request");
  CHECK(code(st.start_run("short", {"FOG-0001", "FOG-0001"}, storage::Purpose::fit, cmd)) == "bad_request");
  CHECK(store.list_runs()->empty());
  CHECK(!st.active_run_id());

  auto id = st.start_run("short", {"FOG-0001"}, storage::Purpose::fit, cmd);
  REQUIRE(id.has_value());
  CHECK(code(st.start_run("short", {"FOG-0002"}, storage::Purpose::fit, cmd)) == "busy");
  CHECK(store.list_runs()->size() == 1);
}

TEST_CASE("station: an abort mid-ramp ends the run and sends the chamber back to the safe setpoint") {
  auto store = memory_store();
  Station st(golden_config(), store);
  SyntheticBench bench(2);
  auto id = st.start_run("short", {"FOG-0002"}, storage::Purpose::fit, {{"cmd", "run.start"}});
  REQUIRE(id.has_value());
  double clock_s = 0.0;
  double sp = 20.0;
  for (int i = 0; i < 661; ++i) sp = st.tick(clock_s++, bench.step(sp)).setpoint_c;
  CHECK(sp == Approx(21.0));  // one minute into the 1 degC/min ramp
  CHECK(st.status()["run"]["phase"] == "heating");

  auto a = st.abort_run("aborted by operator: door open", {{"cmd", "run.abort"}});
  REQUIRE(a.has_value());
  CHECK(st.tick(clock_s++, bench.step(sp)).setpoint_c == 20.0);
  auto d = store.get_run(*id);
  CHECK(d->run.state == storage::RunState::aborted);
  CHECK(d->run.state_reason == "aborted by operator: door open");
  CHECK(store.list_models("FOG-0002")->empty());  // no fit on an aborted run
  auto kinds = event_kinds(store, *id);
  CHECK(std::count(kinds.begin(), kinds.end(), "command") == 2);  // start and abort
  CHECK(std::count(kinds.begin(), kinds.end(), "phase") >= 2);
  CHECK(*store.count_samples(*id) == 661);
}

TEST_CASE("station: a settle that is never met fails the run at its timeout") {
  auto store = memory_store();
  Station st(golden_config(), store);
  SyntheticBench bench(1);
  bench.t1_c[0] = 35.0;  // a hot coil that cannot cool in 5 min
  bench.t2_c[0] = 35.0;
  auto id = st.start_run("settle", {"FOG-0001"}, storage::Purpose::fit, {{"cmd", "run.start"}});
  REQUIRE(id.has_value());
  double clock_s = 0;
  run_to_end(st, bench, clock_s, 1000);
  auto d = store.get_run(*id);
  CHECK(d->run.state == storage::RunState::failed);
  CHECK_THAT(d->run.state_reason, Catch::Contains("settle"));
  CHECK(states(store, *id) == std::vector<std::string>{"pending", "settling", "failed"});
}

TEST_CASE("station: a settle that is met moves the run from settling to running") {
  auto store = memory_store();
  Station st(golden_config(), store);
  SyntheticBench bench(1);
  auto id = st.start_run("settle", {"FOG-0001"}, storage::Purpose::fit, {{"cmd", "run.start"}});
  double clock_s = 0;
  run_to_end(st, bench, clock_s, 1000);
  CHECK(states(store, *id) == std::vector<std::string>{"pending", "settling", "running", "completed"});
  auto rows = store.get_samples(*id, 0, 0, 1);
  CHECK(rows->at(0).phase == model::Phase::settle);
}

TEST_CASE("station: quality flags for readings that are missing, lost or implausible") {
  auto store = memory_store();
  Station st(golden_config(), store);
  SyntheticBench bench(2);
  auto id = st.start_run("short", {"FOG-0001", "FOG-0002"}, storage::Purpose::fit, {{"cmd", "run.start"}});
  TickInput in = bench.step(20);
  in.units[0].gyro_dph.reset();       // no frames this second
  in.units[1].frames_lost = 3;
  in.units[1].t2_c = 400.0;           // a broken sensor reading
  st.tick(0, in);
  TickInput gap = bench.step(20);
  gap.chamber_link_down = true;
  gap.chamber_c.reset();
  gap.chamber_alarm = true;
  st.tick(1, gap);
  auto u0 = store.get_samples(*id, 0, 0, 10);
  auto u1 = store.get_samples(*id, 1, 0, 10);
  CHECK(u0->at(0).flags == model::flag::missing);
  CHECK(std::isnan(u0->at(0).gyro_dph));
  CHECK(u1->at(0).flags == (model::flag::frames_lost | model::flag::out_of_range));
  CHECK(u0->at(1).flags == (model::flag::missing | model::flag::link_gap));
  auto kinds = event_kinds(store, *id);
  CHECK(std::count(kinds.begin(), kinds.end(), "alarm") == 1);
  CHECK(std::count(kinds.begin(), kinds.end(), "fault") == 1);
}

TEST_CASE("station: shutdown aborts the active run, a restart marks a crashed run interrupted") {
  auto store = memory_store();
  SyntheticBench bench(1);
  std::int64_t a = 0, b = 0;
  {
    Station st(golden_config(), store);
    a = *st.start_run("short", {"FOG-0001"}, storage::Purpose::fit, {{"cmd", "run.start"}});
    for (int i = 0; i < 5; ++i) st.tick(i, bench.step(20));
    st.shutdown("fogbenchd stopping: SIGTERM");
    CHECK(store.get_run(a)->run.state == storage::RunState::aborted);
    CHECK(store.get_run(a)->run.state_reason == "fogbenchd stopping: SIGTERM");
  }
  {
    Station st(golden_config(), store);  // crashes: never shut down
    b = *st.start_run("short", {"FOG-0001"}, storage::Purpose::fit, {{"cmd", "run.start"}});
    for (int i = 0; i < 5; ++i) st.tick(i, bench.step(20));
  }
  Station restarted(golden_config(), store);
  auto ids = restarted.recover();
  REQUIRE(ids.has_value());
  CHECK(*ids == std::vector<std::int64_t>{b});
  CHECK(store.get_run(b)->run.state == storage::RunState::interrupted);
  CHECK(store.get_run(a)->run.state == storage::RunState::aborted);
}

TEST_CASE("station: a run with seconds not read is still fitted (the gaps are flagged and bridged)") {
  auto store = memory_store();
  Station st(golden_config(), store);
  SyntheticBench bench(1);
  auto id = st.start_run("short", {"FOG-0001"}, storage::Purpose::fit, {{"cmd", "run.start"}});
  REQUIRE(id.has_value());
  double sp = 20.0;
  for (int k = 0; st.active_run_id() && k < 5000; ++k) {
    TickInput in = bench.step(sp);
    if (k % 97 == 50) in.units[0].gyro_dph.reset();  // a second without usable frames
    if (k % 131 == 70) in.units[0].t1_c.reset();      // a thermistor read that failed
    sp = st.tick(k, in).setpoint_c;
  }
  CHECK(store.get_run(*id)->run.state == storage::RunState::completed);
  auto m = store.current_model("FOG-0001");
  REQUIRE(m.has_value());
  CHECK(m->has_value());
}

TEST_CASE("station: with analysis.causal_lags a fitted model's rate term is held at a lag the firmware meets") {
  auto store = memory_store();
  Station st(golden_config({{"analysis", {{"causal_lags", true}}}}), store, 1.0,
             [] { return std::string("2026-01-01T00:00:00Z"); });
  SyntheticBench bench(1);
  double clock_s = 0.0;
  REQUIRE(st.start_run("short", {"FOG-0001"}, storage::Purpose::fit, {{"cmd", "run.start"}}).has_value());
  run_to_end(st, bench, clock_s);
  auto m = store.current_model("FOG-0001");
  REQUIRE(m.has_value());
  REQUIRE(m->has_value());
  auto model = model::model_from_text((*m)->model_json);
  REQUIRE(model.has_value());
  REQUIRE(model->terms.size() == 2);
  CHECK(model::term_key(model->terms[0].term).starts_with("d(T1)"));
  CHECK(model->terms[0].term.lag.seconds >= 30);  // the synthetic drift's own lag is 0
  CHECK(model::firmware::compile(*model).has_value());
  // The unconstrained fit of the same drift has no firmware form: that is what the hold is for.
  model::Model at_zero = *model;
  at_zero.terms[0].term.lag.seconds = 0;
  CHECK_FALSE(model::firmware::compile(at_zero).has_value());
}
