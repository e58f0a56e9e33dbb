// The station's live compensation (live_compensation.hpp) on the synthetic bench: the stored and
// published compensated rate equals model::firmware's Compensator run offline over the stored
// inputs (to 1e-9 deg/h), null without a model and through the warm-up, restarted by a gap, and
// carried across a daemon restart and run.resume. The live daemon on the mock bench:
// e2e_live_compensation_test.cpp.
#include "fixture.hpp"

#include <cmath>

#include "fogbench/daemon/live_compensation.hpp"
#include "fogbench/model/firmware.hpp"
#include "fogbench/model/json.hpp"
#include "fogbench/storage/models.hpp"

using namespace fogbench;
using namespace fogbench::daemon;
using namespace fogbench::daemon::test;
using nlohmann::json;

namespace {

std::vector<storage::SampleRow> all_rows(storage::Store& store, std::int64_t run, int unit) {
  auto rows = store.get_samples(run, unit, 0, 1000000);
  REQUIRE(rows.has_value());
  return *rows;
}

model::firmware::Program program_of(storage::Store& store, const std::string& serial) {
  auto rec = store.current_model(serial);
  REQUIRE(rec.has_value());
  REQUIRE(rec->has_value());
  auto m = model::model_from_text((*rec)->model_json);
  REQUIRE(m.has_value());
  auto p = model::firmware::compile(*m);
  REQUIRE(p.has_value());
  return *p;
}

// The offline reference, written from the documented rule (docs/daemon.md "Live compensation"),
// not from the daemon's code: a fresh Compensator from the first sample and after every sample
// whose T1 or T2 is missing or flagged out_of_range; the first warm_up_samples of each stretch
// null; gyro_dph minus the drift otherwise.
std::vector<double> offline(const model::firmware::Program& p, const std::vector<storage::SampleRow>& rows) {
  const int warm = model::firmware::warm_up_samples(p);
  std::vector<double> out;
  std::optional<model::firmware::Compensator> c;
  int k = 0;
  for (const auto& r : rows) {
    if (!std::isfinite(r.t1_c) || !std::isfinite(r.t2_c) || (r.flags & model::flag::out_of_range)) {
      c.reset();
      k = 0;
      out.push_back(NAN);
      continue;
    }
    if (!c) c.emplace(p);
    const double mu = c->step({r.t1_c, r.t2_c, r.chamber_c, r.since_power_on_s});
    out.push_back(k++ >= warm && std::isfinite(r.gyro_dph) ? r.gyro_dph - mu : NAN);
  }
  return out;
}

// Stored live series against the offline one: the same nulls, values to 1e-9 deg/h.
void check_equal(const std::vector<storage::SampleRow>& rows, const std::vector<double>& ref, std::size_t& values) {
  REQUIRE(rows.size() == ref.size());
  values = 0;
  for (std::size_t i = 0; i < rows.size(); ++i) {
    INFO("sample " << i << " t_s " << rows[i].t_s);
    REQUIRE(std::isfinite(rows[i].compensated_dph) == std::isfinite(ref[i]));
    if (std::isfinite(ref[i])) {
      REQUIRE(std::abs(rows[i].compensated_dph - ref[i]) <= 1e-9);
      ++values;
    }
  }
}

// The paper's model with its lag of 38 s. The synthetic bench's drift has no lag, so the model
// fitted on it has lags of a few seconds, which the causal firmware form refuses (a d() needs
// at least 30 s): each unit gets this one stored after its fitted one, as a newer version.
void store_paper_model(storage::Store& store, const std::string& serial) {
  model::Model m;
  m.mu0_dph = -8.0;
  for (auto [text, coef] : {std::pair{"d(T1)@38", -2.7}, std::pair{"grad@38", -0.4}}) {
    model::FittedTerm f;
    f.term = *model::parse_term(text);
    f.coef = coef;
    m.terms.push_back(f);
  }
  storage::NewModel nm;
  nm.serial = serial;
  nm.model_json = model::to_json(m).dump();
  REQUIRE(store.put_model(nm).has_value());
}

// A fit run without a model (all null), then the paper's model stored for both units.
std::int64_t fit_first(Station& st, storage::Store& store, SyntheticBench& bench, double& clock_s) {
  auto fit = st.start_run("short", {"FOG-0001", "FOG-0002"}, storage::Purpose::fit, {{"cmd", "run.start"}});
  REQUIRE(fit.has_value());
  run_to_end(st, bench, clock_s);
  REQUIRE(store.current_model("FOG-0001")->has_value());
  // Without a model the whole fit run was null, stored and pushed.
  for (const auto& r : all_rows(store, *fit, 0)) REQUIRE(std::isnan(r.compensated_dph));
  for (const char* serial : {"FOG-0001", "FOG-0002"}) store_paper_model(store, serial);
  return *fit;
}

json live_note(storage::Store& store, std::int64_t run) {
  auto d = store.get_run(run);
  REQUIRE(d.has_value());
  for (const auto& e : d->events) {
    auto j = json::parse(e.detail_json, nullptr, false);
    if (e.kind == storage::EventKind::note && j.is_object() && j.contains("live_compensation")) return j["live_compensation"];
  }
  return nullptr;
}

}  // namespace

TEST_CASE("live compensation: the stored and published series equals the firmware program run offline over the stored inputs") {
  auto store = memory_store();
  Station st(golden_config(), store, 1.0, [] { return std::string("2026-01-01T00:00:00Z"); });
  std::vector<json> published;
  st.set_publisher([&](const json& m) { published.push_back(m); });
  SyntheticBench bench(2);
  double clock_s = 0.0;
  const auto fit = fit_first(st, store, bench, clock_s);
  CHECK(live_note(store, fit)[0]["none"] == "no model");
  for (const auto& m : published)
    if (m["type"] == "sample") REQUIRE(m["compensated_dph"].is_null());

  // A second run of the same serials: compensated live with the model of the first.
  published.clear();
  auto v = st.start_run("short", {"FOG-0001", "FOG-0002"}, storage::Purpose::verify, {{"cmd", "run.start"}});
  REQUIRE(v.has_value());
  run_to_end(st, bench, clock_s);
  const json note = live_note(store, *v);
  REQUIRE(note.is_array());
  CHECK(note[0]["model_id"] == (*store.current_model("FOG-0001"))->id);
  for (int unit : {0, 1}) {
    const auto p = program_of(store, unit == 0 ? "FOG-0001" : "FOG-0002");
    const int warm = model::firmware::warm_up_samples(p);
    CHECK(warm == 68);  // d(T1)@38: the slope's 60 earlier samples and 8 s of delay beyond its own 30
    CHECK(note[unit]["warm_up_s"].get<double>() == Approx(warm));
    const auto rows = all_rows(store, *v, unit);
    const auto ref = offline(p, rows);
    std::size_t values = 0;
    check_equal(rows, ref, values);
    CHECK(values == rows.size() - static_cast<std::size_t>(warm));  // no gaps: null only while warming up
    // Published as stored, field compensated_dph.
    std::size_t seen = 0;
    for (const auto& m : published) {
      if (m["type"] != "sample" || m["unit"] != unit) continue;
      const auto& r = rows.at(seen++);
      REQUIRE(m["t_s"] == r.t_s);
      if (std::isfinite(r.compensated_dph)) REQUIRE(m["compensated_dph"].get<double>() == r.compensated_dph);
      else REQUIRE(m["compensated_dph"].is_null());
    }
    CHECK(seen == rows.size());
  }
}

TEST_CASE("live compensation: a second with a coil temperature missing is null and the compensator warms up again") {
  auto store = memory_store();
  Station st(golden_config(), store, 1.0, [] { return std::string("2026-01-01T00:00:00Z"); });
  SyntheticBench bench(2);
  double clock_s = 0.0;
  fit_first(st, store, bench, clock_s);
  auto v = st.start_run("short", {"FOG-0001", "FOG-0002"}, storage::Purpose::verify, {{"cmd", "run.start"}});
  REQUIRE(v.has_value());
  double sp = st.status()["setpoint_c"].get<double>();
  for (int k = 0; st.active_run_id(); ++k) {
    TickInput in = bench.step(sp);
    if (k >= 900 && k < 903) in.units[0].t1_c.reset();  // unit 0: three seconds of T1 lost mid-ramp
    if (k == 1200) in.units[0].gyro_dph.reset();        // unit 0: one second of the gyro lost
    sp = st.tick(clock_s, in).setpoint_c;
    clock_s += 1.0;
  }
  const auto p = program_of(store, "FOG-0001");
  const int warm = model::firmware::warm_up_samples(p);
  const auto rows = all_rows(store, *v, 0);
  std::size_t values = 0;
  check_equal(rows, offline(p, rows), values);
  // Null from the gap through the warm-up after it; the gyro's lost second alone is null.
  for (int i = 900; i < 903 + warm; ++i) CHECK(std::isnan(rows.at(static_cast<std::size_t>(i)).compensated_dph));
  CHECK(std::isfinite(rows.at(static_cast<std::size_t>(903 + warm)).compensated_dph));
  CHECK(std::isnan(rows.at(1200).compensated_dph));
  CHECK(std::isfinite(rows.at(1201).compensated_dph));
  CHECK(values == rows.size() - 3 - 2 * static_cast<std::size_t>(warm) - 1);
  // Unit 1 lost nothing: one warm-up only.
  const auto rows1 = all_rows(store, *v, 1);
  check_equal(rows1, offline(program_of(store, "FOG-0002"), rows1), values);
  CHECK(values == rows1.size() - static_cast<std::size_t>(model::firmware::warm_up_samples(program_of(store, "FOG-0002"))));
}

TEST_CASE("live compensation: across a daemon restart and run.resume the state is rebuilt from the stored seconds") {
  auto store = memory_store();
  SyntheticBench bench(2);
  double clock_s = 0.0;
  std::int64_t run = 0;
  std::int64_t model_id = 0;
  double sp = 20.0;
  {
    Station st(golden_config(), store, 1.0, [] { return std::string("2026-01-01T00:00:00Z"); });
    fit_first(st, store, bench, clock_s);
    model_id = (*store.current_model("FOG-0001"))->id;
    run = *st.start_run("short", {"FOG-0001", "FOG-0002"}, storage::Purpose::verify, {{"cmd", "run.start"}});
    const double c0 = clock_s;
    for (int k = 0; k < 700; ++k) sp = st.tick(c0 + k, bench.step(sp, 1000.0 + k)).setpoint_c;
    // The daemon dies here, the run left running.
  }
  // Meanwhile a newer model of FOG-0001 is stored: the resumed run keeps the one it started with.
  {
    auto rec = store.current_model("FOG-0001");
    storage::NewModel nm;
    nm.serial = "FOG-0001";
    auto newer = model::model_from_text((*rec)->model_json);
    REQUIRE(newer.has_value());
    newer->mu0_dph += 100.0;  // a series made with it would be 100 deg/h off
    nm.model_json = model::to_json(*newer).dump();
    REQUIRE(store.put_model(nm).has_value());
    REQUIRE((*store.current_model("FOG-0001"))->id != model_id);
  }
  Station st(golden_config(), store, 1.0, [] { return std::string("2026-01-01T00:00:00Z"); });
  REQUIRE(st.recover().has_value());
  auto started_with = store.get_model(model_id);
  REQUIRE(started_with.has_value());
  const auto started_model = model::model_from_text(started_with->model_json);
  REQUIRE(started_model.has_value());
  const auto p = *model::firmware::compile(*started_model);
  const int warm = model::firmware::warm_up_samples(p);

  SECTION("after a gap of 50 s: null through the gap and one warm-up after it") {
    REQUIRE(st.resume_run(run, 1699.0 + 50.0, {{"cmd", "run.resume"}}).has_value());
    for (int k = 0; st.active_run_id(); ++k) sp = st.tick(2000.0 + k, bench.step(sp, 1750.0 + k)).setpoint_c;
    const auto rows = all_rows(store, run, 0);
    std::size_t values = 0;
    check_equal(rows, offline(p, rows), values);
    for (std::size_t i = 700; i < 750 + static_cast<std::size_t>(warm); ++i) CHECK(std::isnan(rows.at(i).compensated_dph));
    CHECK(std::isfinite(rows.at(750 + static_cast<std::size_t>(warm)).compensated_dph));
    CHECK(values == rows.size() - 50 - 2 * static_cast<std::size_t>(warm));
  }
  SECTION("resumed within the second: no gap, no second warm-up, the series as if never stopped") {
    REQUIRE(st.resume_run(run, 1699.0, {{"cmd", "run.resume"}}).has_value());
    for (int k = 0; st.active_run_id(); ++k) sp = st.tick(2000.0 + k, bench.step(sp, 1700.0 + k)).setpoint_c;
    const auto rows = all_rows(store, run, 0);
    std::size_t values = 0;
    check_equal(rows, offline(p, rows), values);
    CHECK(values == rows.size() - static_cast<std::size_t>(warm));
    CHECK(std::isfinite(rows.at(700).compensated_dph));
  }
}

TEST_CASE("live compensation: a model the firmware form refuses is null for the run, and the note says why") {
  auto store = memory_store();
  // A d(T1) with lag 5 s would read 25 s of the future in causal form.
  model::Model m;
  m.mu0_dph = -8.0;
  model::FittedTerm f;
  f.term = *model::parse_term("d(T1)@5");
  f.coef = -2.7;
  m.terms.push_back(f);
  REQUIRE_FALSE(model::firmware::compile(m).has_value());
  storage::NewModel nm;
  nm.serial = "FOG-0001";
  nm.model_json = model::to_json(m).dump();
  REQUIRE(model::model_from_text(nm.model_json).has_value());
  REQUIRE(store.put_model(nm).has_value());
  Station st(golden_config(), store, 1.0, [] { return std::string("2026-01-01T00:00:00Z"); });
  SyntheticBench bench(1);
  double clock_s = 0.0;
  auto v = st.start_run("short", {"FOG-0001"}, storage::Purpose::verify, {{"cmd", "run.start"}});
  REQUIRE(v.has_value());
  for (int k = 0; k < 200; ++k) st.tick(clock_s++, bench.step(20.0));
  const json note = live_note(store, *v);
  CHECK_THAT(note[0]["none"].get<std::string>(), Catch::Contains("no firmware form") && Catch::Contains("d(T1)@5"));
  for (const auto& r : all_rows(store, *v, 0)) REQUIRE(std::isnan(r.compensated_dph));
}
