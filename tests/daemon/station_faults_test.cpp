// The station's answers to a chamber that misbehaves, without I/O: the link lost (held within
// link_loss.tolerance_s, aborted past it or at once under safe_abort), the controller's alarm,
// and a chamber that does not follow its setpoint (tracking.*); a store that is full or refuses
// writes. Whole runs in milliseconds.
#include "fixture.hpp"

#include <sqlite3.h>

using namespace fogbench;
using namespace fogbench::daemon;
using namespace fogbench::daemon::test;
using nlohmann::json;

namespace {

struct Rig {
  storage::Store store = memory_store();
  std::unique_ptr<Station> st;
  SyntheticBench bench{1};
  double clock_s = 0.0;
  double sp_c = 20.0;
  std::int64_t run = 0;

  explicit Rig(DaemonConfig c) {
    st = std::make_unique<Station>(std::move(c), store, 1.0, [] { return std::string("2026-01-01T00:00:00Z"); });
    auto id = st->start_run("short", {"FOG-0001"}, storage::Purpose::fit, {{"cmd", "run.start"}});
    REQUIRE(id.has_value());
    run = *id;
    sp_c = st->status()["setpoint_c"].get<double>();
  }
  // One second; `edit` changes what the chamber reports.
  template <class Edit>
  void tick(Edit edit) {
    TickInput in = bench.step(sp_c);
    edit(in);
    sp_c = st->tick(clock_s, in).setpoint_c;
    clock_s += 1.0;
  }
  void tick() {
    tick([](TickInput&) {});
  }
  storage::RunRecord record() {
    auto d = store.get_run(run);
    REQUIRE(d.has_value());
    return d->run;
  }
};

template <class T>
std::string code_of_error(const ApiResult<T>& r) {
  return r ? "ok" : std::string(to_string(r.error().code));
}

void link_down(TickInput& in) {
  in.chamber_link_down = true;
  in.chamber_c.reset();
  in.chamber_setpoint_c.reset();
}

}  // namespace

TEST_CASE("station faults: a link gap within link_loss.tolerance_s holds the profile clock and flags the gap") {
  auto c = golden_config();
  c.link_loss.tolerance_s = 30;
  Rig r(std::move(c));
  for (int i = 0; i < 700; ++i) r.tick();  // into the ramp to 25 degC (hold 600 s, then 1 degC/min)
  const double sp_before_c = r.sp_c;
  REQUIRE(sp_before_c > 20.5);
  for (int i = 0; i < 20; ++i) r.tick(link_down);
  // Held: the setpoint stood still through the gap.
  CHECK(r.sp_c == sp_before_c);
  CHECK(r.st->status()["run"]["profile_held_s"].get<double>() == Approx(20.0));
  r.tick();
  CHECK(r.st->active_run_id().has_value());
  // Every second of the run is stored; the gap's 20 are flagged link_gap and missing.
  CHECK(*r.store.count_samples(r.run, 0) == 721);
  auto rows = r.store.get_samples(r.run, 0, 700, 21);
  REQUIRE(rows->size() == 21);
  for (int i = 0; i < 20; ++i) {
    CHECK((rows->at(i).flags & model::flag::link_gap) != 0);
    CHECK((rows->at(i).flags & model::flag::missing) != 0);
    CHECK(rows->at(i).setpoint_c == sp_before_c);
  }
  CHECK((rows->at(20).flags & model::flag::link_gap) == 0);
  // The profile ends 20 s later than without the gap: 1801 + 20 ticks in all.
  int ticks = 721;
  while (r.st->active_run_id() && ticks < 5000) {
    r.tick();
    ++ticks;
  }
  CHECK(ticks == 1821);
  CHECK(r.record().state == storage::RunState::completed);
}

TEST_CASE("station faults: a gap longer than link_loss.tolerance_s aborts and commands the safe setpoint") {
  auto c = golden_config();
  c.link_loss.tolerance_s = 30;
  c.safe_setpoint_c = 15;
  Rig r(std::move(c));
  for (int i = 0; i < 700; ++i) r.tick();
  for (int i = 0; i < 40 && r.st->active_run_id(); ++i) r.tick(link_down);
  CHECK_FALSE(r.st->active_run_id().has_value());
  CHECK(r.sp_c == 15.0);  // the server writes it as soon as the link is back
  CHECK(r.record().state == storage::RunState::aborted);
  CHECK_THAT(r.record().state_reason, Catch::Contains("link_loss.tolerance_s 30"));
}

TEST_CASE("station faults: link_loss.policy safe_abort aborts at the first second without the chamber") {
  auto c = golden_config();
  c.link_loss.policy = LinkLossConfig::Policy::safe_abort;
  Rig r(std::move(c));
  for (int i = 0; i < 10; ++i) r.tick();
  r.tick(link_down);
  CHECK_FALSE(r.st->active_run_id().has_value());
  CHECK_THAT(r.record().state_reason, Catch::Contains("safe_abort"));
  CHECK(*r.store.count_samples(r.run, 0) == 11);
}

TEST_CASE("station faults: the chamber's alarm aborts the run with the reason stored") {
  Rig r(golden_config());
  for (int i = 0; i < 10; ++i) r.tick();
  r.tick([](TickInput& in) { in.chamber_alarm = true; });
  CHECK_FALSE(r.st->active_run_id().has_value());
  CHECK(r.record().state == storage::RunState::aborted);
  CHECK(r.record().state_reason == "chamber alarm");
}

TEST_CASE("station faults: a frozen PV while the setpoint moves aborts after tracking.frozen_s") {
  auto c = golden_config();
  c.tracking.frozen_s = 60;
  Rig r(std::move(c));
  // 600 s hold at 20 degC: the synthetic PV sits exactly at 20 degC, the setpoint does not
  // move, and nothing trips.
  for (int i = 0; i < 600; ++i) r.tick();
  REQUIRE(r.st->active_run_id().has_value());
  // The ramp at 1 degC/min: 60 s moves the setpoint 1 degC, past the 0.5 degC that separates
  // a frozen PV from a chamber at rest.
  for (int i = 0; i < 200 && r.st->active_run_id(); ++i) r.tick([](TickInput& in) { in.chamber_c = 20.0; });
  CHECK_FALSE(r.st->active_run_id().has_value());
  CHECK_THAT(r.record().state_reason, Catch::Contains("frozen"));
}

TEST_CASE("station faults: |PV - setpoint| over tracking.max_error_c for tracking.for_s aborts") {
  auto c = golden_config();
  c.tracking.max_error_c = 2;
  c.tracking.for_s = 100;
  Rig r(std::move(c));
  for (int i = 0; i < 100; ++i) r.tick();
  // A chamber stuck 3 degC low, changing in its last digits so it is not "frozen".
  int n = 0;
  for (; n < 300 && r.st->active_run_id(); ++n)
    r.tick([n](TickInput& in) { in.chamber_c = 17.0 + 0.01 * (n % 2); });
  CHECK_FALSE(r.st->active_run_id().has_value());
  CHECK(n > 100);
  CHECK_THAT(r.record().state_reason, Catch::Contains("tracking.max_error_c 2"));
}

TEST_CASE("station faults: a full disk aborts the run, commands the safe setpoint and is reported in status") {
  char tmpl[] = "/tmp/fogbench-diskfull-XXXXXX";
  const std::filesystem::path dir = ::mkdtemp(tmpl);
  const auto db = dir / "fogbench.db";
  {
    auto s = storage::Store::open(db);  // the schema, so the limit below leaves room for samples only
    REQUIRE(s.has_value());
  }
  storage::OpenOptions o;
  // 64 KiB over the empty store: some hundreds of one-unit seconds, well under short.profile's 1801.
  o.size_limit_bytes = static_cast<std::int64_t>(std::filesystem::file_size(db)) + 64 * 1024;
  auto opened = storage::Store::open(db, o);
  REQUIRE(opened.has_value());
  auto c = golden_config();
  c.safe_setpoint_c = 15;
  Station st(std::move(c), *opened, 1.0, [] { return std::string("2026-01-01T00:00:00Z"); });
  SyntheticBench bench(1);
  auto id = st.start_run("short", {"FOG-0001"}, storage::Purpose::fit, {{"cmd", "run.start"}});
  REQUIRE(id.has_value());
  double clock_s = 0;
  const int ticks = run_to_end(st, bench, clock_s, 5000);
  CHECK(ticks < 1801);
  CHECK_FALSE(st.active_run_id().has_value());
  const json s = st.status();
  CHECK(s["setpoint_c"] == 15.0);
  REQUIRE(s["last_run"].is_object());
  CHECK(s["last_run"]["run_id"] == *id);
  // Aborted, not failed: a fault of the station, the chamber made safe (docs/daemon.md).
  CHECK(s["last_run"]["state"] == "aborted");
  CHECK_THAT(s["last_run"]["reason"].get<std::string>(), Catch::Contains("storage full (disk_full)"));
  // The size limit's reserve took the run's end: stored, with its quality note.
  CHECK(s["last_run"]["recorded"] == true);
  auto d = opened->get_run(*id);
  REQUIRE(d.has_value());
  CHECK(d->run.state == storage::RunState::aborted);
  CHECK_THAT(d->run.state_reason, Catch::Contains("storage full"));
  CHECK(d->run.ended_at.has_value());
  CHECK(d->events.back().kind == storage::EventKind::state);
  CHECK(d->events.at(d->events.size() - 2).detail_json.find("quality") != std::string::npos);
  // Every second before the one that did not fit is stored, in order.
  const auto n = *opened->count_samples(*id, 0);
  CHECK(n == ticks - 1);
  auto last = opened->get_samples(*id, 0, n - 1, 1);
  REQUIRE(last->size() == 1);
  CHECK(last->at(0).t_s == static_cast<double>(n - 1));
  CHECK(opened->integrity_check()->empty());
  // The daemon goes on: ticks without a run still answer.
  CHECK(st.tick(clock_s, bench.step(15)).setpoint_c == 15.0);
  std::error_code ec;
  std::filesystem::remove_all(dir, ec);
}

TEST_CASE("station faults: a run's end the store refuses is kept, reported and written once the store takes it") {
  char tmpl[] = "/tmp/fogbench-locked-XXXXXX";
  const std::filesystem::path dir = ::mkdtemp(tmpl);
  const auto db = dir / "fogbench.db";
  storage::OpenOptions o;
  o.busy_timeout_ms = 0;  // a write lock held elsewhere fails at once (busy) instead of waiting
  auto opened = storage::Store::open(db, o);
  REQUIRE(opened.has_value());
  auto c = golden_config();
  c.safe_setpoint_c = 15;
  Station st(std::move(c), *opened, 1.0, [] { return std::string("2026-01-01T00:00:00Z"); });
  SyntheticBench bench(1);
  auto id = st.start_run("short", {"FOG-0001"}, storage::Purpose::fit, {{"cmd", "run.start"}});
  REQUIRE(id.has_value());
  double clock_s = 0, sp_c = 20;
  for (int i = 0; i < 100; ++i, clock_s += 1) sp_c = st.tick(clock_s, bench.step(sp_c)).setpoint_c;

  // Another connection (an operator's sqlite3 shell, say) holds the write lock: nothing the
  // station writes gets in, neither the next second nor the run's end.
  sqlite3* other = nullptr;
  REQUIRE(sqlite3_open(db.c_str(), &other) == SQLITE_OK);
  REQUIRE(sqlite3_exec(other, "BEGIN IMMEDIATE", nullptr, nullptr, nullptr) == SQLITE_OK);
  sp_c = st.tick(clock_s, bench.step(sp_c)).setpoint_c;
  clock_s += 1;
  CHECK_FALSE(st.active_run_id().has_value());
  CHECK(sp_c == 15.0);
  json s = st.status();
  CHECK(s["last_run"]["state"] == "aborted");
  CHECK_THAT(s["last_run"]["reason"].get<std::string>(), Catch::Contains("storage failed (busy)"));
  CHECK(s["last_run"]["recorded"] == false);
  // The store still says running; the station knows better and says so.
  CHECK(opened->get_run(*id)->run.state == storage::RunState::running);
  const json end = st.unrecorded_end(*id);
  REQUIRE(end.is_object());
  CHECK(end["state"] == "aborted");
  CHECK(end["recorded"] == false);
  // Still locked: the ticks keep trying (every 10 s) and the daemon keeps going.
  for (int i = 0; i < 25; ++i, clock_s += 1) CHECK(st.tick(clock_s, bench.step(15)).setpoint_c == 15.0);
  CHECK(st.status()["last_run"]["recorded"] == false);

  REQUIRE(sqlite3_exec(other, "ROLLBACK", nullptr, nullptr, nullptr) == SQLITE_OK);
  sqlite3_close(other);
  for (int i = 0; i < 10 && !st.status()["last_run"]["recorded"].get<bool>(); ++i, clock_s += 1)
    st.tick(clock_s, bench.step(15));
  CHECK(st.status()["last_run"]["recorded"] == true);
  CHECK(st.unrecorded_end(*id).is_null());
  auto d = opened->get_run(*id);
  REQUIRE(d.has_value());
  CHECK(d->run.state == storage::RunState::aborted);
  CHECK_THAT(d->run.state_reason, Catch::Contains("storage failed (busy)"));
  // In order: the quality note, then the state change, as if written at once.
  REQUIRE(d->events.size() >= 2);
  CHECK(d->events.at(d->events.size() - 2).kind == storage::EventKind::note);
  CHECK(d->events.back().kind == storage::EventKind::state);
  CHECK(*opened->count_samples(*id, 0) == 100);
  std::error_code ec;
  std::filesystem::remove_all(dir, ec);
}

TEST_CASE("station faults: a store that refuses the interrupted marks at start-up is retried, no run starts meanwhile") {
  char tmpl[] = "/tmp/fogbench-recover-XXXXXX";
  const std::filesystem::path dir = ::mkdtemp(tmpl);
  const auto db = dir / "fogbench.db";
  storage::OpenOptions o;
  o.busy_timeout_ms = 0;
  auto opened = storage::Store::open(db, o);
  REQUIRE(opened.has_value());
  SyntheticBench bench(1);
  std::int64_t run = 0;
  {
    Station st(golden_config(), *opened, 1.0, [] { return std::string("2026-01-01T00:00:00Z"); });
    run = *st.start_run("short", {"FOG-0001"}, storage::Purpose::fit, {{"cmd", "run.start"}});
    for (int k = 0; k < 30; ++k) st.tick(k, bench.step(20));
    // The daemon dies here, the run left running.
  }
  sqlite3* other = nullptr;
  REQUIRE(sqlite3_open(db.c_str(), &other) == SQLITE_OK);
  REQUIRE(sqlite3_exec(other, "BEGIN IMMEDIATE", nullptr, nullptr, nullptr) == SQLITE_OK);

  auto c = golden_config();
  c.safe_setpoint_c = 15;
  Station st(std::move(c), *opened, 1.0, [] { return std::string("2026-01-01T00:00:00Z"); });
  auto rec = st.recover();
  REQUIRE_FALSE(rec.has_value());
  // The daemon runs on: the chamber is sent to the safe setpoint, status says what is pending.
  double clock_s = 0;
  CHECK(st.tick(clock_s++, bench.step(20)).setpoint_c == 15.0);
  json s = st.status();
  REQUIRE(s["recovery"].is_object());
  CHECK_THAT(s["recovery"]["error"].get<std::string>(), Catch::Contains("busy"));
  // No run starts or resumes: the stale one would be taken for it.
  auto refused = st.start_run("short", {"FOG-0001"}, storage::Purpose::fit, {{"cmd", "run.start"}});
  REQUIRE_FALSE(refused.has_value());
  CHECK(refused.error().code == ErrorCode::internal);
  CHECK_THAT(refused.error().message, Catch::Contains("not yet marked interrupted"));
  CHECK(code_of_error(st.resume_run(run, 0, {})) == "internal");
  CHECK(opened->get_run(run)->run.state == storage::RunState::running);

  REQUIRE(sqlite3_exec(other, "ROLLBACK", nullptr, nullptr, nullptr) == SQLITE_OK);
  sqlite3_close(other);
  // Retried every 10 s: not at once, then within the next 10 ticks.
  st.tick(clock_s++, bench.step(15));
  CHECK(st.status()["recovery"].is_object());
  for (int i = 0; i < 10; ++i) st.tick(clock_s++, bench.step(15));
  CHECK(st.status()["recovery"].is_null());
  CHECK(opened->get_run(run)->run.state == storage::RunState::interrupted);
  CHECK(st.start_run("short", {"FOG-0001"}, storage::Purpose::fit, {{"cmd", "run.start"}}).has_value());
  std::error_code ec;
  std::filesystem::remove_all(dir, ec);
}

TEST_CASE("station faults: an interrupted run resumes where its profile clock stood, the gap stored flagged") {
  auto store = memory_store();
  std::int64_t run = 0;
  double sp_c = 20.0;
  SyntheticBench bench(1);
  {
    Station st(golden_config(), store, 1.0, [] { return std::string("2026-01-01T00:00:00Z"); });
    auto id = st.start_run("short", {"FOG-0001"}, storage::Purpose::fit, {{"cmd", "run.start"}});
    REQUIRE(id.has_value());
    run = *id;
    // 700 s: into the ramp; wall time = 1000 + run second.
    for (int k = 0; k < 700; ++k) sp_c = st.tick(k, bench.step(sp_c, 1000.0 + k)).setpoint_c;
    // The daemon dies here: no shutdown, the run left running.
  }
  Station st(golden_config(), store, 1.0, [] { return std::string("2026-01-01T00:00:00Z"); });
  REQUIRE(st.recover().has_value());
  CHECK(store.get_run(run)->run.state == storage::RunState::interrupted);
  CHECK(code_of_error(st.resume_run(run + 1, 0, {})) == "not_found");

  // 50 s later (the last stored second was at wall time 1699).
  auto r = st.resume_run(run, 1699.0 + 50.0, {{"cmd", "run.resume"}, {"run_id", run}});
  REQUIRE(r.has_value());
  CHECK(code_of_error(st.resume_run(run, 1750.0, {})) == "busy");
  // The quality counts go on from the store: the 50 s gap is 50 seconds flagged (the synthetic
  // bench's own seconds have no flag).
  CHECK(st.status()["run"]["quality"][0]["samples_flagged"] == 50);
  CHECK(st.status()["run"]["quality"][0]["frames_lost"] == 0);
  // The next ticks carry on the run clock after the gap; the profile goes on from 700 s.
  int ticks = 0;
  for (double clock_s = 5000; st.active_run_id() && ticks < 5000; clock_s += 1, ++ticks)
    sp_c = st.tick(clock_s, bench.step(sp_c, 1750.0 + ticks)).setpoint_c;
  auto d = store.get_run(run);
  CHECK(d->run.state == storage::RunState::completed);
  // The whole profile is 1801 s of profile clock; 700 were run before, 1101 after, and the 50 s
  // gap (seconds 700 .. 749) is stored flagged in between.
  CHECK(ticks == 1101);
  CHECK(*store.count_samples(run, 0) == 700 + 50 + 1101);
  auto rows = store.get_samples(run, 0, 0, 10000);
  for (std::size_t i = 0; i < rows->size(); ++i) {
    CHECK(rows->at(i).t_s == static_cast<double>(i));
    const bool in_gap = i >= 700 && i < 750;
    CHECK(((rows->at(i).flags & model::flag::link_gap) != 0) == in_gap);
  }
  // The held setpoint through the gap is the one of second 699, and the first resumed second
  // steps on from it by one second of the 1 degC/min ramp.
  CHECK(rows->at(749).setpoint_c == rows->at(699).setpoint_c);
  CHECK(rows->at(750).setpoint_c == Approx(rows->at(699).setpoint_c + 1.0 / 60.0));
}

namespace {
// A writer that dies in the middle of a resume's gap, as fogbenchd killed while its writer thread
// writes it: the seconds go to the store, of a gap only its first slice.
class DiesInGap final : public SampleWriter {
 public:
  explicit DiesInGap(storage::Store& s) : inline_(s) {}
  void append(std::int64_t run_id, std::vector<storage::SampleRow> rows, double clock_s) override {
    inline_.append(run_id, std::move(rows), clock_s);
  }
  void append_gap(std::int64_t run_id, SampleGap gap, double clock_s) override {
    inline_.append(run_id, gap_rows(gap, gap.from_s, std::min(gap.to_s, gap.from_s + kGapSliceSeconds)), clock_s);
  }
  std::optional<SampleWriteFailure> take_failure() override { return inline_.take_failure(); }
  bool drain(std::chrono::milliseconds) override { return true; }
  std::optional<double> oldest_pending_clock_s() const override { return std::nullopt; }
  std::size_t pending() const override { return 0; }

 private:
  InlineSampleWriter inline_;
};
}  // namespace

TEST_CASE("station faults: a resume killed while writing its gap is completed by the next resume, the gap stored once") {
  auto store = memory_store();
  std::int64_t run = 0;
  double sp_c = 20.0;
  SyntheticBench bench(1);
  {
    Station st(golden_config(), store, 1.0, [] { return std::string("2026-01-01T00:00:00Z"); });
    run = *st.start_run("short", {"FOG-0001"}, storage::Purpose::fit, {{"cmd", "run.start"}});
    // 700 s: wall time = 1000 + run second, the last stored at 1699.
    for (int k = 0; k < 700; ++k) sp_c = st.tick(k, bench.step(sp_c, 1000.0 + k)).setpoint_c;
  }
  const double away_s = 5000.0;  // the bench without the daemon, wall s (time scale 1)
  {
    // The first resume: only its gap's first slice is stored before the daemon dies.
    Station st(golden_config(), store, 1.0, [] { return std::string("2026-01-01T00:00:00Z"); });
    DiesInGap dies(store);
    st.set_sample_writer(&dies);
    REQUIRE(st.recover().has_value());
    REQUIRE(st.resume_run(run, 1699.0 + away_s, {{"cmd", "run.resume"}, {"run_id", run}}).has_value());
    CHECK(*store.count_samples(run, 0) == 700 + static_cast<std::int64_t>(kGapSliceSeconds));
  }
  // The second, 100 s later: the gap ends where the run clock stands now (5100 s after second
  // 699), its stored slice is not added again.
  Station st(golden_config(), store, 1.0, [] { return std::string("2026-01-01T00:00:00Z"); });
  REQUIRE(st.recover().has_value());
  REQUIRE(store.get_run(run)->run.state == storage::RunState::interrupted);
  REQUIRE(st.resume_run(run, 1699.0 + away_s + 100.0, {{"cmd", "run.resume"}, {"run_id", run}}).has_value());
  CHECK(st.status()["run"]["quality"][0]["samples_flagged"] == away_s + 100.0);
  const auto n = *store.count_samples(run, 0);
  CHECK(n == 700 + static_cast<std::int64_t>(away_s) + 100);
  auto rows = store.get_samples(run, 0, 0, n);
  REQUIRE(static_cast<std::int64_t>(rows->size()) == n);
  for (std::size_t i = 0; i < rows->size(); ++i) {
    INFO("row " << i);
    CHECK(rows->at(i).t_s == static_cast<double>(i));
    CHECK(((rows->at(i).flags & model::flag::link_gap) != 0) == (i >= 700));
  }
  // Each resume said what it stored; the second that it completed the first's gap.
  auto d = store.get_run(run);
  std::vector<json> resumes;
  for (const auto& e : d->events) {
    json j = json::parse(e.detail_json);
    if (e.kind == storage::EventKind::fault && j.value("resumed", false)) resumes.push_back(j);
  }
  REQUIRE(resumes.size() == 2);
  CHECK(resumes[0]["gap_from_s"] == 700.0);
  CHECK(resumes[0]["gap_s"] == away_s);
  CHECK_FALSE(resumes[0].contains("gap_stored_before_s"));
  CHECK(resumes[1]["gap_from_s"] == 700.0 + kGapSliceSeconds);
  CHECK(resumes[1]["gap_stored_before_s"] == kGapSliceSeconds);
  CHECK(resumes[1]["gap_started_s"] == 700.0);
  CHECK(resumes[1]["gap_to_s"] == 700.0 + away_s + 100.0);
  // The profile clock stood through the whole gap: the run goes on from 700 s of profile, 1101
  // seconds to its end.
  int ticks = 0;
  for (double clock_s = 10000; st.active_run_id() && ticks < 5000; clock_s += 1, ++ticks)
    sp_c = st.tick(clock_s, bench.step(sp_c, 1699.0 + away_s + 100.0 + ticks)).setpoint_c;
  CHECK(ticks == 1101);
  CHECK(store.get_run(run)->run.state == storage::RunState::completed);
}

TEST_CASE("station faults: run.start and run.resume are refused while the chamber link is down, accepted once it is back") {
  storage::Store store = memory_store();
  Station st(golden_config(), store, 1.0, [] { return std::string("2026-01-01T00:00:00Z"); });
  SyntheticBench bench{1};
  // Before the first poll nothing is known: nothing is refused for it (see the Rig above).
  TickInput in = bench.step(20.0);
  link_down(in);
  st.tick(0.0, in);
  auto refused = st.start_run("short", {"FOG-0001"}, storage::Purpose::fit, {{"cmd", "run.start"}});
  REQUIRE_FALSE(refused.has_value());
  CHECK(code_of_error(refused) == "unavailable");
  CHECK_THAT(refused.error().message, Catch::Contains("chamber link is down"));
  // Nothing was stored for it: a refused run.start changes nothing.
  CHECK(store.list_runs({})->empty());
  CHECK(code_of_error(st.resume_run(1, 0.0, {{"cmd", "run.resume"}})) == "unavailable");
  st.tick(1.0, bench.step(20.0));
  CHECK(code_of_error(st.start_run("short", {"FOG-0001"}, storage::Purpose::fit, {{"cmd", "run.start"}})) == "ok");
}

TEST_CASE("station faults: the seconds of a frozen PV are stored flagged pv_frozen once the setpoint has moved 0.5 degC") {
  auto c = golden_config();
  c.tracking.frozen_s = 120;
  Rig r(std::move(c));
  // The hold: a live PV, changing in its last digit; nothing flagged.
  for (int i = 0; i < 600; ++i) r.tick([i](TickInput& in) { in.chamber_c = 20.01 + 0.01 * (i % 2); });
  // The ramp at 1 degC/min with the PV stuck at 20 degC from 600 s: the setpoint has moved
  // 0.5 degC after 30 s; from then on each second is flagged, until 120 s of it abort the run.
  for (int i = 0; i < 300 && r.st->active_run_id(); ++i) r.tick([](TickInput& in) { in.chamber_c = 20.0; });
  REQUIRE_FALSE(r.st->active_run_id().has_value());
  CHECK_THAT(r.record().state_reason, Catch::Contains("frozen"));
  const auto n = *r.store.count_samples(r.run, 0);
  auto rows = r.store.get_samples(r.run, 0, 0, static_cast<int>(n));
  REQUIRE(rows.has_value());
  int flagged = 0, first = -1;
  for (std::size_t i = 0; i < rows->size(); ++i)
    if (rows->at(i).flags & model::flag::pv_frozen) {
      ++flagged;
      if (first < 0) first = static_cast<int>(i);
    }
  // The PV stopped changing at 600 s (it was exactly 20 all along); 0.5 degC of ramp is 30 s,
  // the abort comes 120 s after the PV last changed. So seconds ~630..720 are flagged.
  CHECK(first >= 625);
  CHECK(first <= 635);
  CHECK(flagged >= 80);
  CHECK(flagged == static_cast<int>(rows->size()) - first);
  for (int i = 0; i < 600; ++i) CHECK((rows->at(static_cast<std::size_t>(i)).flags & model::flag::pv_frozen) == 0);
}

TEST_CASE("station faults: a run that fails after the loop fell behind real time says so first in its reason") {
  // The "short" profile has no settle to fail, so a station of its own runs "settle" (timeout 5 min)
  // on seconds the loop was too late to read: nothing read, the settle cannot be judged.
  storage::Store store = memory_store();
  Station st(golden_config(), store, 200.0, [] { return std::string("2026-01-01T00:00:00Z"); });
  auto id = st.start_run("settle", {"FOG-0001"}, storage::Purpose::fit, {{"cmd", "run.start"}});
  REQUIRE(id.has_value());
  double clock_s = 0;
  for (int i = 0; i < 400 && st.active_run_id(); ++i) {
    TickInput in;
    in.units.resize(1);
    in.late = true;
    st.tick(clock_s, in);
    clock_s += 1;
  }
  REQUIRE_FALSE(st.active_run_id().has_value());
  auto d = store.get_run(*id);
  REQUIRE(d.has_value());
  CHECK(d->run.state == storage::RunState::failed);
  INFO(d->run.state_reason);
  CHECK(d->run.state_reason.starts_with("the acquisition fell behind real time ("));
  CHECK_THAT(d->run.state_reason, Catch::Contains("time scale 200"));
  CHECK_THAT(d->run.state_reason, Catch::Contains("settle"));  // the original reason follows
}

TEST_CASE("station faults: a chamber link lost as the loop falls behind is named first in the abort reason") {
  // The chamber gone: its calls wait out their timeouts, so the same seconds come late. The
  // reason names the link (the cause), the late seconds after it, not "the host is too busy".
  auto c = golden_config();
  c.link_loss.tolerance_s = 20;
  storage::Store store = memory_store();
  Station st(c, store, 20.0, [] { return std::string("2026-01-01T00:00:00Z"); });
  auto id = st.start_run("short", {"FOG-0001"}, storage::Purpose::fit, {{"cmd", "run.start"}});
  REQUIRE(id.has_value());
  double clock_s = 0;
  auto tick = [&](bool link_down, bool late) {
    TickInput in;
    in.units.resize(1);
    in.chamber_c = 20.0;
    if (link_down) in.chamber_c.reset();
    in.chamber_link_down = link_down;
    in.late = late;
    st.tick(clock_s, in);
    clock_s += 1;
  };
  for (int i = 0; i < 30; ++i) tick(false, false);
  // The first late second comes a second before the link is known down (the timed-out call).
  tick(false, true);
  for (int i = 0; i < 60 && st.active_run_id(); ++i) tick(true, i % 2 == 0);
  REQUIRE_FALSE(st.active_run_id().has_value());
  auto d = store.get_run(*id);
  REQUIRE(d.has_value());
  INFO(d->run.state_reason);
  CHECK(d->run.state == storage::RunState::aborted);
  CHECK(d->run.state_reason.starts_with("chamber link lost for "));
  CHECK_THAT(d->run.state_reason, Catch::Contains("s were not read in time"));
  CHECK_THAT(d->run.state_reason, !Catch::Contains("too busy"));
}

TEST_CASE("station faults: the gyro stream's problems are recorded as fault events of the run, at their second") {
  Rig r(golden_config());
  for (int i = 0; i < 10; ++i) r.tick();
  r.tick([](TickInput& in) { in.gyro_stream_events = {"/dev/ttyUSB0: 12 bytes of garbage before a sync word"}; });
  r.tick();
  r.tick([](TickInput& in) {
    in.gyro_stream_events = {"/dev/ttyUSB0: frame at byte 4096: bad CRC", "/dev/ttyUSB0: frame cut at byte 5000"};
  });
  auto d = r.store.get_run(r.run);
  REQUIRE(d.has_value());
  std::vector<std::pair<double, std::string>> faults;
  for (const auto& e : d->events) {
    const auto detail = json::parse(e.detail_json);
    if (e.kind == storage::EventKind::fault && detail.contains("gyro_stream"))
      faults.emplace_back(e.t_s.value_or(-1.0), detail["gyro_stream"].get<std::string>());
  }
  REQUIRE(faults.size() == 3);
  CHECK(faults[0] == std::pair<double, std::string>{10.0, "/dev/ttyUSB0: 12 bytes of garbage before a sync word"});
  CHECK(faults[1].first == 12.0);
  CHECK(faults[2].second == "/dev/ttyUSB0: frame cut at byte 5000");
  // Nothing else about the seconds changes: every one stored.
  CHECK(*r.store.count_samples(r.run, 0) == 13);
}
