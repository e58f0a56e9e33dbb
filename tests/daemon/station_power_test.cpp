// The station records each gyro's power-on as seen in its frames: the time since power-on per
// sample (unknown, never guessed, when not seen), and a note event at each power-on or restart of a
// unit in the run, decided from the start-up frames the gyro sends, never from the seconds'
// timing (docs/daemon.md "Power-on").
#include "fixture.hpp"

using namespace fogbench;
using namespace fogbench::daemon;
using namespace fogbench::daemon::test;
using nlohmann::json;

namespace {

// A second in which a unit sent nothing: no frames, no rate.
void silent(TickInput& in, std::size_t u) {
  in.units[u].gyro_dph.reset();
  in.units[u].frames = 0;
}

// A second in which a unit's frames include the first of its start-up (warming_up, counter at 0).
void starts(TickInput& in, std::size_t u) { in.units[u].gyro_starts = 1; }

std::vector<json> power_events(storage::Store& s, std::int64_t run) {
  auto d = s.get_run(run);
  REQUIRE(d.has_value());
  std::vector<json> out;
  for (const auto& e : d->events) {
    auto j = json::parse(e.detail_json);
    if (e.kind == storage::EventKind::note && j.contains("gyro_power")) {
      j["t_s"] = e.t_s ? json(*e.t_s) : json(nullptr);
      out.push_back(j);
    }
  }
  return out;
}

}  // namespace

TEST_CASE("station: the time since a gyro's power-on is recorded when seen, and a power cycle restarts it") {
  auto store = memory_store();
  Station st(golden_config(), store);
  SyntheticBench bench(2);
  std::vector<json> published;
  st.set_publisher([&](const json& m) {
    if (m.value("type", "") == "sample") published.push_back(m);
  });
  double sp = 20;
  // Daemon seconds 0..4: FOG-0001 sends from the start (its power-on is before the daemon's
  // time: unknown), FOG-0002 is silent; at 5 its start-up frames come: powered on at 4, the
  // start of the period they came in.
  for (int k = 0; k <= 5; ++k) {
    TickInput in = bench.step(sp);
    if (k < 5) silent(in, 1);
    if (k == 5) starts(in, 1);
    sp = st.tick(k, in).setpoint_c;
  }
  auto id = st.start_run("short", {"FOG-0001", "FOG-0002"}, storage::Purpose::fit, {{"cmd", "run.start"}});
  REQUIRE(id.has_value());
  // The run starts at daemon second 6 (run time 0). FOG-0002 is silent at 10..12 and sends its
  // start-up frames at 13: a restart, powered on at 12. The silence alone said nothing.
  for (int k = 6; k <= 15; ++k) {
    TickInput in = bench.step(sp);
    if (k >= 10 && k <= 12) silent(in, 1);
    if (k == 13) starts(in, 1);
    sp = st.tick(k, in).setpoint_c;
  }
  auto u0 = store.get_samples(*id, 0, 0, 100).value();
  auto u1 = store.get_samples(*id, 1, 0, 100).value();
  REQUIRE(u1.size() == 10);
  // Daemon second k is run time k - 6; FOG-0002's time since power-on is k - 4 until its
  // restart is seen at 13 (through the silence too: nothing said it was off), then k - 12.
  const double expect[] = {2, 3, 4, 5, 6, 7, 8, 1, 2, 3};
  for (std::size_t i = 0; i < u1.size(); ++i) {
    INFO("run time " << u1[i].t_s);
    if (std::isnan(expect[i])) CHECK(std::isnan(u1[i].since_power_on_s));
    else CHECK(u1[i].since_power_on_s == expect[i]);
    CHECK(std::isnan(u0[i].since_power_on_s));  // FOG-0001's power-on was never seen
  }
  // The CSV export: FOG-0002 has the column, FOG-0001's run says it was not recorded.
  CHECK(store.export_run(*id, 1).value().has_power_on());
  CHECK_FALSE(store.export_run(*id, 0).value().has_power_on());
  // On the wire too (null when unknown).
  REQUIRE(published.size() == 20);
  CHECK(published[1]["serial"] == "FOG-0002");
  CHECK(published[1]["since_power_on_s"] == 2.0);
  CHECK(published[0]["since_power_on_s"].is_null());

  const auto ev = power_events(store, *id);
  REQUIRE(ev.size() == 3);
  CHECK(ev[0]["serial"] == "FOG-0001");
  CHECK(ev[0]["gyro_power"] == "power_on_not_seen");
  CHECK(ev[1]["serial"] == "FOG-0002");
  CHECK(ev[1]["gyro_power"] == "on");
  CHECK(ev[1]["since_power_on_s"] == 2.0);
  CHECK(ev[2]["gyro_power"] == "restart");
  CHECK(ev[2]["t_s"] == 7.0);  // daemon second 13
  CHECK(ev[2]["since_power_on_s"] == 1.0);
}

TEST_CASE("station: seconds the loop was late, empty or bunched, are no power cycle") {
  auto store = memory_store();
  Station st(golden_config(), store);
  SyntheticBench bench(2);
  double sp = 20;
  for (int k = 0; k < 3; ++k) {
    TickInput in = bench.step(sp);
    silent(in, 0);
    silent(in, 1);
    sp = st.tick(k, in).setpoint_c;
  }
  auto id = st.start_run("short", {"FOG-0001", "FOG-0002"}, storage::Purpose::fit, {{"cmd", "run.start"}});
  REQUIRE(id.has_value());
  // At 3 the start-up frames come: both on at 2. At 6 a second not read (the loop late), at
  // 7..10 seconds read but empty (the bench behind a busy host), at 11 their frames in a burst:
  // no power-off, no restart, the time since power-on grows by one a second throughout.
  for (int k = 3; k <= 14; ++k) {
    TickInput in = bench.step(sp);
    if (k == 3) {
      starts(in, 0);
      starts(in, 1);
    }
    if (k == 6) {
      in.gyro_read = false;
      in.late = true;
    }
    if (k >= 6 && k <= 10) {
      silent(in, 0);
      silent(in, 1);
    }
    if (k == 11) in.units[0].frames = in.units[1].frames = 600;
    sp = st.tick(k, in).setpoint_c;
  }
  auto u0 = store.get_samples(*id, 0, 0, 100).value();
  REQUIRE(u0.size() == 12);
  for (std::size_t i = 0; i < u0.size(); ++i) CHECK(u0[i].since_power_on_s == 1.0 + static_cast<double>(i));
  const auto ev = power_events(store, *id);
  // The frames at 3 came in the run's first second: one power_on per unit, no power_off.
  REQUIRE(ev.size() == 2);
  for (const auto& e : ev) {
    CHECK(e["gyro_power"] == "power_on");
    CHECK(e["t_s"] == 0.0);
  }
}
