// Tests of the SQLite store: schema creation and migration, refusal of foreign and newer files,
// runs/units/events/samples, export/import, models, verifications, interrupted runs, and
// write failures (read-only, disk full) that must be values and lose nothing stored.
#include <catch2/catch.hpp>

#include <sqlite3.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "fogbench/storage/csv.hpp"
#include "fogbench/storage/store.hpp"

using namespace fogbench;
using namespace fogbench::storage;
using Catch::Matchers::Contains;

namespace {

// A fresh directory per test case, removed at the end of it.
struct TempDir {
  std::filesystem::path dir;
  TempDir() {
    static std::atomic<int> counter{0};
    dir = std::filesystem::temp_directory_path() /
          ("fogbench_store_test_" + std::to_string(::getpid()) + "_" +
           std::to_string(counter++));
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::permissions(dir, std::filesystem::perms::owner_all, ec);
    std::filesystem::remove_all(dir, ec);
  }
  std::filesystem::path operator/(const std::string& name) const { return dir / name; }
};

Store open_ok(const std::filesystem::path& path, const OpenOptions& options = {}) {
  auto s = Store::open(path, options);
  if (!s) FAIL("open " << path << ": " << s.error().message);
  return std::move(*s);
}

// Raw SQLite access, to build old or foreign files and look at what the store wrote.
struct Raw {
  sqlite3* db = nullptr;
  explicit Raw(const std::filesystem::path& path) {
    REQUIRE(sqlite3_open(path.c_str(), &db) == SQLITE_OK);
  }
  ~Raw() { sqlite3_close(db); }
  void exec(const std::string& sql) {
    char* err = nullptr;
    const int rc = sqlite3_exec(db, sql.c_str(), nullptr, nullptr, &err);
    INFO(sql << ": " << (err ? err : ""));
    sqlite3_free(err);
    REQUIRE(rc == SQLITE_OK);
  }
  std::string text(const std::string& sql) {
    sqlite3_stmt* st = nullptr;
    REQUIRE(sqlite3_prepare_v2(db, sql.c_str(), -1, &st, nullptr) == SQLITE_OK);
    std::string out;
    if (sqlite3_step(st) == SQLITE_ROW && sqlite3_column_text(st, 0))
      out = reinterpret_cast<const char*>(sqlite3_column_text(st, 0));
    sqlite3_finalize(st);
    return out;
  }
  long long integer(const std::string& sql) { return std::stoll(text(sql)); }
};

NewRun two_unit_run(std::string profile = "qualification") {
  NewRun r;
  r.profile_name = std::move(profile);
  r.profile_text = "hold 23 C 1 h\nramp 60 C at 1 C/min\n";
  r.config_json = R"({"units":2,"rate_hz":1})";
  r.time_scale = 1.0;
  r.unit_serials = {"FOG-001", "FOG-002"};
  return r;
}

SampleRow sample(int unit, double t_s, model::Phase phase = model::Phase::hold) {
  SampleRow s;
  s.unit_index = unit;
  s.t_s = t_s;
  s.wall_time = 1.7e9 + t_s;
  s.setpoint_c = 23;
  s.chamber_c = 23.5 + 0.001 * t_s;
  s.gyro_dph = 0.01 * t_s + unit;
  s.frames = 2000;
  s.t1_c = 23.1 + 0.001 * t_s;
  s.t2_c = 23.2 + 0.001 * t_s;
  s.phase = phase;
  s.step = 1;
  s.flags = 0;
  return s;
}

// The schema of version 1 exactly as it was published: databases in the field were made by
// it, so migration is tested from this text, not from whatever migration 1 says today.
constexpr const char* kSchemaV1 = R"sql(
CREATE TABLE runs (
  id            INTEGER PRIMARY KEY,
  created_at    TEXT NOT NULL,
  profile_name  TEXT NOT NULL,
  profile_text  TEXT NOT NULL DEFAULT '',
  purpose       TEXT NOT NULL CHECK (purpose IN ('fit', 'verify')),
  state         TEXT NOT NULL DEFAULT 'pending'
                CHECK (state IN ('pending', 'settling', 'running', 'completed', 'aborted',
                                 'failed', 'interrupted')),
  state_reason  TEXT NOT NULL DEFAULT '',
  config_json   TEXT NOT NULL DEFAULT '{}' CHECK (json_valid(config_json)),
  started_at    TEXT,
  ended_at      TEXT,
  time_scale    REAL NOT NULL DEFAULT 1.0 CHECK (time_scale > 0)
);
CREATE INDEX runs_state ON runs (state);
CREATE TABLE run_units (
  run_id      INTEGER NOT NULL REFERENCES runs (id) ON DELETE CASCADE,
  unit_index  INTEGER NOT NULL CHECK (unit_index >= 0),
  serial      TEXT NOT NULL,
  PRIMARY KEY (run_id, unit_index)
) WITHOUT ROWID;
CREATE INDEX run_units_serial ON run_units (serial);
CREATE TABLE samples (
  run_id      INTEGER NOT NULL,
  unit_index  INTEGER NOT NULL,
  t_s         REAL NOT NULL,
  wall_time   REAL,
  setpoint_c  REAL,
  chamber_c   REAL,
  gyro_dph    REAL,
  frames      INTEGER,
  t1_c        REAL,
  t2_c        REAL,
  phase       INTEGER CHECK (phase BETWEEN 0 AND 4),
  step        INTEGER,
  flags       INTEGER CHECK (flags BETWEEN 0 AND 255),
  PRIMARY KEY (run_id, unit_index, t_s),
  FOREIGN KEY (run_id, unit_index) REFERENCES run_units (run_id, unit_index) ON DELETE CASCADE
) WITHOUT ROWID;
CREATE TABLE run_events (
  id      INTEGER PRIMARY KEY,
  run_id  INTEGER NOT NULL REFERENCES runs (id) ON DELETE CASCADE,
  t_s     REAL,
  at      TEXT NOT NULL,
  kind    TEXT NOT NULL
          CHECK (kind IN ('state', 'phase', 'command', 'alarm', 'fault', 'note')),
  detail  TEXT NOT NULL DEFAULT '{}' CHECK (json_valid(detail))
);
CREATE INDEX run_events_run ON run_events (run_id, id);
CREATE VIEW sample_view AS
SELECT run_id, unit_index, t_s, wall_time, setpoint_c, chamber_c, gyro_dph, frames, t1_c, t2_c,
       CASE phase WHEN 0 THEN 'unknown' WHEN 1 THEN 'settle' WHEN 2 THEN 'hold'
                  WHEN 3 THEN 'heating' WHEN 4 THEN 'cooling' END AS phase,
       step, flags
FROM samples;
PRAGMA user_version = 1;
PRAGMA application_id = 1179600706;
)sql";

}  // namespace

TEST_CASE("store: a new file gets the current schema, WAL and the fogbench id", "[store][schema]") {
  TempDir tmp;
  const auto path = tmp / "new.db";
  {
    Store s = open_ok(path);
    CHECK(s.schema_version() == Store::current_schema_version());
    CHECK(Store::current_schema_version() >= 4);  // 4: unit lots and the plant outbox (issue 14)
    CHECK(s.path() == path);
  }
  Raw raw(path);
  CHECK(raw.text("PRAGMA journal_mode") == "wal");
  CHECK(raw.integer("PRAGMA user_version") == Store::current_schema_version());
  CHECK(raw.integer("PRAGMA application_id") == 0x464F4742);
  for (const char* table : {"runs", "run_units", "samples", "run_events", "models", "verifications"})
    CHECK(raw.integer(std::string("SELECT count(*) FROM sqlite_schema WHERE name = '") + table +
                      "'") == 1);
}

TEST_CASE("store: an in-memory database works (no WAL file to make)", "[store][schema]") {
  Store s = open_ok(":memory:");
  CHECK(s.schema_version() == Store::current_schema_version());
  const auto run = s.create_run(two_unit_run()).value();
  const SampleRow rows[] = {sample(0, 0)};
  REQUIRE(s.append_samples(run, rows).has_value());
  CHECK(s.count_samples(run).value() == 1);
}

TEST_CASE("store: migration from version 0 and version 1", "[store][schema]") {
  TempDir tmp;
  SECTION("version 0: an existing empty SQLite file") {
    const auto path = tmp / "v0.db";
    { Raw raw(path); raw.exec("PRAGMA user_version = 0"); }
    Store s = open_ok(path);
    CHECK(s.schema_version() == Store::current_schema_version());
    CHECK(s.create_run(two_unit_run()).has_value());
  }
  SECTION("version 1: data kept, model tables added") {
    const auto path = tmp / "v1.db";
    {
      Raw raw(path);
      raw.exec(kSchemaV1);
      raw.exec(
          "INSERT INTO runs (id, created_at, profile_name, purpose, state) "
          "VALUES (7, '2026-01-01T00:00:00.000Z', 'old', 'fit', 'completed');"
          "INSERT INTO run_units VALUES (7, 0, 'FOG-OLD');"
          "INSERT INTO samples (run_id, unit_index, t_s, gyro_dph, t1_c, t2_c) "
          "VALUES (7, 0, 0, 0.5, 20, 21), (7, 0, 1, 0.6, 20, 21);");
    }
    Store s = open_ok(path);
    CHECK(s.schema_version() == Store::current_schema_version());
    // A unit from before version 4 has no lot.
    CHECK_FALSE(s.get_run(7)->run.units.at(0).lot.has_value());
    // Samples from before version 3 have no time since power-on: the export says not recorded.
    auto old = s.export_run(7, 0);
    REQUIRE(old.has_value());
    CHECK_FALSE(old->has_power_on());
    auto run = s.get_run(7);
    REQUIRE(run.has_value());
    CHECK(run->run.profile_name == "old");
    CHECK(run->run.units.at(0).serial == "FOG-OLD");
    CHECK(s.count_samples(7).value() == 2);
    auto m = s.put_model({"FOG-OLD", 7, std::nullopt, "{}", "ols", "t1"});
    REQUIRE(m.has_value());
    CHECK(m->version == 1);
    CHECK(s.integrity_check().value().empty());
  }
  SECTION("a read-only open of an old file is refused, and the file is left as it was") {
    const auto path = tmp / "v1ro.db";
    { Raw raw(path); raw.exec(kSchemaV1); }
    OpenOptions ro;
    ro.read_only = true;
    auto s = Store::open(path, ro);
    REQUIRE_FALSE(s.has_value());
    CHECK(s.error().code == StoreErrc::schema_too_old);
    CHECK_THAT(s.error().message, Contains("open it once read-write"));
    Raw raw(path);
    CHECK(raw.integer("PRAGMA user_version") == 1);
  }
}

TEST_CASE("store: newer, foreign and non-database files are refused untouched", "[store][schema]") {
  TempDir tmp;
  SECTION("a newer schema version") {
    const auto path = tmp / "future.db";
    {
      Raw raw(path);
      raw.exec("CREATE TABLE runs (id INTEGER PRIMARY KEY, future_column TEXT);"
               "PRAGMA user_version = 9; PRAGMA application_id = 1179600706;");
    }
    auto s = Store::open(path);
    REQUIRE_FALSE(s.has_value());
    CHECK(s.error().code == StoreErrc::schema_too_new);
    CHECK_THAT(s.error().message, Contains("schema version 9 is newer"));
    CHECK_THAT(s.error().message, Contains(path.string()));
    Raw raw(path);
    CHECK(raw.integer("PRAGMA user_version") == 9);
    CHECK(raw.text("PRAGMA journal_mode") == "delete");  // not even switched to WAL
  }
  SECTION("another application's database") {
    const auto path = tmp / "other.db";
    { Raw raw(path); raw.exec("CREATE TABLE photos (id INTEGER PRIMARY KEY, name TEXT)"); }
    auto s = Store::open(path);
    REQUIRE_FALSE(s.has_value());
    CHECK(s.error().code == StoreErrc::not_fogbench);
    Raw raw(path);
    CHECK(raw.integer("SELECT count(*) FROM sqlite_schema") == 1);
  }
  SECTION("a different application_id") {
    const auto path = tmp / "app.db";
    { Raw raw(path); raw.exec("PRAGMA application_id = 42"); }
    auto s = Store::open(path);
    REQUIRE_FALSE(s.has_value());
    CHECK(s.error().code == StoreErrc::not_fogbench);
    CHECK_THAT(s.error().message, Contains("0x0000002A"));
  }
  SECTION("a text file") {
    const auto path = tmp / "notes.db";
    std::ofstream(path) << "time_s,gyro_dph,t1_c,t2_c\n0,0,0,0\n"
                        << std::string(2000, 'x') << "\n";
    auto s = Store::open(path);
    REQUIRE_FALSE(s.has_value());
    CHECK(s.error().code == StoreErrc::corrupt);
    CHECK_THAT(s.error().message, Contains("not a database"));
  }
  SECTION("a directory that does not exist") {
    auto s = Store::open(tmp / "no/such/dir/x.db");
    REQUIRE_FALSE(s.has_value());
    CHECK(s.error().code == StoreErrc::open_failed);
    CHECK_THAT(s.error().message, Contains("no/such/dir/x.db"));
  }
  SECTION("a missing file with create = false") {
    OpenOptions o;
    o.create = false;
    auto s = Store::open(tmp / "missing.db", o);
    REQUIRE_FALSE(s.has_value());
    CHECK(s.error().code == StoreErrc::open_failed);
    CHECK_FALSE(std::filesystem::exists(tmp / "missing.db"));
  }
}

TEST_CASE("store: runs, units, states and events", "[store][runs]") {
  TempDir tmp;
  int tick = 0;
  OpenOptions o;
  // 2026-01-01T00:00:00Z plus one second per call: every time stamp is predictable.
  o.clock = [&tick] {
    return std::chrono::system_clock::time_point(std::chrono::seconds(1767225600 + tick++));
  };
  Store s = open_ok(tmp / "runs.db", o);

  auto id = s.create_run(two_unit_run());
  REQUIRE(id.has_value());
  auto d = s.get_run(*id);
  REQUIRE(d.has_value());
  CHECK(d->run.id == *id);
  CHECK(d->run.created_at == "2026-01-01T00:00:00.000Z");
  CHECK(d->run.profile_name == "qualification");
  CHECK(d->run.profile_text == two_unit_run().profile_text);
  CHECK(d->run.purpose == Purpose::fit);
  CHECK(d->run.state == RunState::pending);
  CHECK(d->run.config_json == R"({"units":2,"rate_hz":1})");
  CHECK_FALSE(d->run.started_at.has_value());
  CHECK_FALSE(d->run.ended_at.has_value());
  REQUIRE(d->run.units.size() == 2);
  CHECK(d->run.units[1].unit_index == 1);
  CHECK(d->run.units[1].serial == "FOG-002");
  REQUIRE(d->events.size() == 1);
  CHECK(d->events[0].kind == EventKind::state);

  REQUIRE(s.set_run_state(*id, RunState::settling, "operator start", 0.0).has_value());
  REQUIRE(s.set_run_state(*id, RunState::running, "settled", 1800.0).has_value());
  REQUIRE(s.add_event(*id, EventKind::command, R"({"cmd":"pause","by":"ann"})", 1900.0));
  REQUIRE(s.add_event(*id, EventKind::alarm, R"({"code":"T_LIMIT"})"));
  REQUIRE(s.set_run_state(*id, RunState::completed, "profile done", 9000.0).has_value());

  d = s.get_run(*id);
  REQUIRE(d.has_value());
  CHECK(d->run.state == RunState::completed);
  CHECK(d->run.state_reason == "profile done");
  // started_at is the first transition out of pending, not the later one to running.
  REQUIRE(d->run.started_at.has_value());
  REQUIRE(d->run.ended_at.has_value());
  CHECK(*d->run.started_at < *d->run.ended_at);
  REQUIRE(d->events.size() == 6);
  CHECK(d->events[1].kind == EventKind::state);
  CHECK(d->events[1].t_s == 0.0);
  const auto detail = nlohmann::json::parse(d->events[2].detail_json);
  CHECK(detail["from"] == "settling");
  CHECK(detail["to"] == "running");
  CHECK(detail["reason"] == "settled");
  CHECK(d->events[3].kind == EventKind::command);
  CHECK(d->events[3].t_s == 1900.0);
  CHECK(d->events[4].kind == EventKind::alarm);
  CHECK_FALSE(d->events[4].t_s.has_value());
  CHECK(d->events[5].detail_json.find("profile done") != std::string::npos);

  SECTION("errors name the problem") {
    auto bad = s.add_event(*id, EventKind::note, "{not json");
    REQUIRE_FALSE(bad.has_value());
    CHECK(bad.error().code == StoreErrc::invalid_argument);
    auto missing = s.set_run_state(999, RunState::running, "x");
    REQUIRE_FALSE(missing.has_value());
    CHECK(missing.error().code == StoreErrc::not_found);
    CHECK_THAT(missing.error().message, Contains("run 999"));
    CHECK(s.get_run(999).error().code == StoreErrc::not_found);
    NewRun r = two_unit_run();
    r.config_json = "[1,";
    CHECK(s.create_run(r).error().code == StoreErrc::invalid_argument);
    r = two_unit_run();
    r.unit_serials = {"A", "A"};  // the same serial twice is allowed (index is the key)
    CHECK(s.create_run(r).has_value());
  }
}

TEST_CASE("store: list_runs filters and pages, newest first", "[store][runs]") {
  TempDir tmp;
  Store s = open_ok(tmp / "list.db");
  NewRun a = two_unit_run("qual");
  NewRun b = two_unit_run("verify-short");
  b.purpose = Purpose::verify;
  b.unit_serials = {"FOG-003"};
  const auto r1 = s.create_run(a).value();
  const auto r2 = s.create_run(b).value();
  const auto r3 = s.create_run(a).value();
  REQUIRE(s.set_run_state(r3, RunState::running, "go").has_value());

  auto all = s.list_runs();
  REQUIRE(all.has_value());
  REQUIRE(all->size() == 3);
  CHECK((*all)[0].id == r3);
  CHECK((*all)[2].id == r1);
  CHECK((*all)[1].units.size() == 1);

  RunFilter f;
  f.purpose = Purpose::verify;
  CHECK(s.list_runs(f)->size() == 1);
  f = {};
  f.serial = "FOG-002";
  auto by_serial = s.list_runs(f).value();
  REQUIRE(by_serial.size() == 2);
  CHECK(by_serial[0].id == r3);
  CHECK(by_serial[1].id == r1);
  f = {};
  f.state = RunState::running;
  REQUIRE(s.list_runs(f)->size() == 1);
  CHECK(s.list_runs(f)->at(0).id == r3);
  f = {};
  f.profile_name = "verify-short";
  CHECK(s.list_runs(f)->at(0).id == r2);
  f = {};
  f.limit = 1;
  f.offset = 1;
  auto page = s.list_runs(f).value();
  REQUIRE(page.size() == 1);
  CHECK(page[0].id == r2);
}

TEST_CASE("store: samples are stored, counted and paged", "[store][samples]") {
  TempDir tmp;
  Store s = open_ok(tmp / "samples.db");
  const auto run = s.create_run(two_unit_run()).value();

  // 100 s of two units, appended one second (two rows) per call as the daemon does.
  for (int t = 0; t < 100; ++t) {
    const SampleRow rows[] = {sample(0, t), sample(1, t)};
    REQUIRE(s.append_samples(run, rows).has_value());
  }
  CHECK(s.count_samples(run).value() == 200);
  CHECK(s.count_samples(run, 1).value() == 100);
  CHECK(s.count_samples(run, 5).value() == 0);

  auto page = s.get_samples(run, 1, 40, 25);
  REQUIRE(page.has_value());
  REQUIRE(page->size() == 25);
  CHECK(page->front().t_s == 40);
  CHECK(page->back().t_s == 64);
  const SampleRow want = sample(1, 40);
  const SampleRow& got = page->front();
  CHECK(got.unit_index == 1);
  CHECK(got.wall_time == want.wall_time);
  CHECK(got.gyro_dph == want.gyro_dph);
  CHECK(got.t1_c == want.t1_c);
  CHECK(got.t2_c == want.t2_c);
  CHECK(got.chamber_c == want.chamber_c);
  CHECK(got.frames == 2000);
  CHECK(got.phase == model::Phase::hold);
  CHECK(got.step == 1);
  CHECK(s.get_samples(run, 1, 95, 25)->size() == 5);
  CHECK(s.get_samples(run, 1, 200, 25)->empty());

  SECTION("a value not read (NaN) is NULL and reads back as NaN") {
    SampleRow gap = sample(0, 100);
    gap.gyro_dph = kNoValue;
    gap.frames.reset();
    gap.step.reset();
    gap.flags = model::flag::missing;
    REQUIRE(s.append_samples(run, std::span(&gap, 1)).has_value());
    auto back = s.get_samples(run, 0, 100, 1).value().at(0);
    CHECK(std::isnan(back.gyro_dph));
    CHECK_FALSE(back.frames.has_value());
    CHECK_FALSE(back.step.has_value());
    CHECK(back.flags == model::flag::missing);
  }
  SECTION("a duplicate time rejects the whole call") {
    const SampleRow rows[] = {sample(0, 100), sample(1, 100), sample(0, 50)};
    auto r = s.append_samples(run, rows);
    REQUIRE_FALSE(r.has_value());
    CHECK(r.error().code == StoreErrc::constraint);
    CHECK_THAT(r.error().message, Contains("unit 0 of run 1 already has a sample at t_s 50"));
    CHECK(s.count_samples(run).value() == 200);  // rows 0 and 1 of the call were rolled back
  }
  SECTION("an unknown unit") {
    const SampleRow rows[] = {sample(2, 100)};
    auto r = s.append_samples(run, rows);
    REQUIRE_FALSE(r.has_value());
    CHECK(r.error().code == StoreErrc::constraint);
    CHECK_THAT(r.error().message, Contains("has no unit 2"));
  }
  SECTION("a NaN time") {
    SampleRow bad = sample(0, 100);
    bad.t_s = kNoValue;
    CHECK(s.append_samples(run, std::span(&bad, 1)).error().code == StoreErrc::invalid_argument);
  }
  SECTION("paging an unknown unit or run") {
    CHECK(s.get_samples(run, 7, 0, 10).error().code == StoreErrc::not_found);
    CHECK_THAT(s.get_samples(run, 7, 0, 10).error().message, Contains("run 1 has no unit 7"));
    CHECK_THAT(s.get_samples(42, 0, 0, 10).error().message, Contains("no run 42"));
    CHECK(s.count_samples(42).error().code == StoreErrc::not_found);
  }
}

TEST_CASE("store: import_run -> export_run gives back the CSV", "[store][export]") {
  TempDir tmp;
  Store s = open_ok(tmp / "io.db");
  // Written by to_csv, so the text is canonical and must come back byte for byte.
  model::RunData src;
  for (int i = 0; i < 500; ++i) {
    src.time_s.push_back(i);
    src.gyro_dph.push_back(0.001 * i + 1.0 / 3.0);
    src.t1_c.push_back(20 + i * 0.0123);
    src.t2_c.push_back(20.5 + i * 0.0121);
    src.setpoint_c.push_back(i < 100 ? 20 : 60);
    src.phase.push_back(i < 100 ? model::Phase::hold : model::Phase::heating);
    src.step.push_back(i < 100 ? 0 : 1);
    src.flags.push_back(i == 250 ? model::flag::frames_lost : 0);
  }
  const std::string csv = to_csv(src);
  CsvOptions co;
  co.source_name = "unit7.csv";
  auto parsed = parse_csv(csv, co);
  REQUIRE(parsed.has_value());

  ImportOptions io;
  io.serial = "FOG-007";
  io.profile_name = "bench import";
  auto id = s.import_run(*parsed, io);
  REQUIRE(id.has_value());
  auto run = s.get_run(*id).value();
  CHECK(run.run.state == RunState::completed);
  CHECK(run.run.state_reason == "imported from unit7.csv");
  CHECK(run.run.units.at(0).serial == "FOG-007");
  CHECK(s.count_samples(*id).value() == 500);

  auto back = s.export_run(*id, 0);
  REQUIRE(back.has_value());
  CHECK(back->name == "run 1 unit 0 (FOG-007)");
  CHECK_FALSE(back->has_chamber());  // not imported, so not exported
  CHECK(to_csv(*back) == csv);

  SECTION("a run without optional columns comes back without them") {
    model::RunData bare;
    bare.name = "bare";
    bare.time_s = {0, 1, 2};
    bare.gyro_dph = {1, 2, 3};
    bare.t1_c = {4, 5, 6};
    bare.t2_c = {7, 8, 9};
    const auto bid = s.import_run(bare, io).value();
    auto e = s.export_run(bid, 0).value();
    CHECK(to_csv(e) == to_csv(bare));
  }
  SECTION("invalid data is refused before anything is written") {
    model::RunData bad = *parsed;
    bad.t2_c.pop_back();
    auto r = s.import_run(bad, io);
    REQUIRE_FALSE(r.has_value());
    CHECK(r.error().code == StoreErrc::invalid_argument);
    CHECK_THAT(r.error().message, Contains("t2_c has 499 values but time_s has 500"));
    ImportOptions no_serial;
    CHECK(s.import_run(*parsed, no_serial).error().code == StoreErrc::invalid_argument);
    CHECK(s.list_runs()->size() == 1);
  }
}

TEST_CASE("store: export leaves out the leading settle samples unless asked", "[store][export]") {
  TempDir tmp;
  Store s = open_ok(tmp / "settle.db");
  const auto run = s.create_run(two_unit_run()).value();
  std::vector<SampleRow> rows;
  for (int t = 0; t < 10; ++t) {
    SampleRow r = sample(0, t, t < 4 ? model::Phase::settle : model::Phase::heating);
    if (t == 6) r.gyro_dph = kNoValue;
    rows.push_back(r);
  }
  REQUIRE(s.append_samples(run, rows).has_value());

  auto d = s.export_run(run, 0);
  REQUIRE(d.has_value());
  CHECK(d->time_s == std::vector<double>{4, 5, 6, 7, 8, 9});
  CHECK(d->phase.front() == model::Phase::heating);
  CHECK(std::isnan(d->gyro_dph[2]));
  CHECK(d->has_setpoint());
  CHECK(d->has_chamber());
  CHECK(d->has_flags());
  CHECK(d->step == std::vector<int>(6, 1));

  ExportOptions all;
  all.include_settle = true;
  CHECK(s.export_run(run, 0, all)->size() == 10);

  SECTION("only settle samples, or none") {
    const SampleRow settle[] = {sample(1, 0, model::Phase::settle)};
    REQUIRE(s.append_samples(run, settle).has_value());
    auto e = s.export_run(run, 1);
    REQUIRE_FALSE(e.has_value());
    CHECK(e.error().code == StoreErrc::not_found);
    CHECK_THAT(e.error().message, Contains("1 settle samples; include_settle exports them"));
    CHECK(s.export_run(run, 3).error().code == StoreErrc::not_found);
  }
}

TEST_CASE("store: models are versioned per serial and keep their lineage", "[store][models]") {
  TempDir tmp;
  Store s = open_ok(tmp / "models.db");
  const auto run = s.create_run(two_unit_run()).value();

  auto a1 = s.put_model({"FOG-001", run, std::nullopt, R"({"k":[1,2]})", "ols", "t1,dt1"});
  REQUIRE(a1.has_value());
  CHECK(a1->version == 1);
  auto b1 = s.put_model({"FOG-002", run, std::nullopt, "{}", "ols", "t1"});
  REQUIRE(b1.has_value());
  CHECK(b1->version == 1);
  auto a2 = s.put_model({"FOG-001", run, a1->id, R"({"k":[1.1,2]})", "ols", "t1,dt1"});
  auto a3 = s.put_model({"FOG-001", std::nullopt, a2->id, R"({"k":[1.2,2]})", "huber", "t1"});
  REQUIRE(a3.has_value());
  CHECK(a2->version == 2);
  CHECK(a3->version == 3);

  auto cur = s.current_model("FOG-001");
  REQUIRE(cur.has_value());
  REQUIRE(cur->has_value());
  CHECK((*cur)->id == a3->id);
  CHECK((*cur)->method == "huber");
  CHECK_FALSE((*cur)->run_id.has_value());
  CHECK((*cur)->parent_id == a2->id);
  CHECK(s.current_model("FOG-404")->has_value() == false);

  auto got = s.get_model(a1->id).value();
  CHECK(got.serial == "FOG-001");
  CHECK(got.model_json == R"({"k":[1,2]})");
  CHECK(got.terms == "t1,dt1");
  CHECK(got.run_id == run);

  auto lineage = s.model_lineage(a3->id);
  REQUIRE(lineage.has_value());
  REQUIRE(lineage->size() == 3);
  CHECK((*lineage)[0].id == a3->id);
  CHECK((*lineage)[1].id == a2->id);
  CHECK((*lineage)[2].id == a1->id);
  CHECK(s.model_lineage(a1->id)->size() == 1);
  CHECK(s.list_models("FOG-001")->size() == 3);
  CHECK(s.list_models("FOG-001")->at(1).version == 2);

  CHECK(s.model_lineage(999).error().code == StoreErrc::not_found);
  CHECK(s.put_model({"FOG-001", std::nullopt, 999, "{}", "", ""}).error().code ==
        StoreErrc::not_found);
  CHECK(s.put_model({"FOG-001", 999, std::nullopt, "{}", "", ""}).error().code ==
        StoreErrc::not_found);
  CHECK(s.put_model({"FOG-001", std::nullopt, std::nullopt, "nope", "", ""}).error().code ==
        StoreErrc::invalid_argument);
  CHECK(s.current_model("FOG-001")->value().version == 3);  // failures took no version
}

TEST_CASE("store: verifications", "[store][models]") {
  TempDir tmp;
  Store s = open_ok(tmp / "verify.db");
  const auto fit_run = s.create_run(two_unit_run()).value();
  const auto model = s.put_model({"FOG-002", fit_run, std::nullopt, "{}", "ols", "t1"}).value();
  NewRun vr = two_unit_run("verify");
  vr.purpose = Purpose::verify;
  const auto run = s.create_run(vr).value();

  auto v1 = s.put_verification({run, 1, model.id, R"({"rms_dph":0.004})", true});
  auto v2 = s.put_verification({run, 0, model.id, R"({"rms_dph":0.09})", false});
  REQUIRE(v1.has_value());
  REQUIRE(v2.has_value());
  auto list = s.list_verifications(run);
  REQUIRE(list.has_value());
  REQUIRE(list->size() == 2);
  CHECK((*list)[0].id == *v1);
  CHECK((*list)[0].unit_index == 1);
  CHECK((*list)[0].pass);
  CHECK((*list)[0].model_id == model.id);
  CHECK((*list)[0].result_json == R"({"rms_dph":0.004})");
  CHECK_FALSE((*list)[1].pass);
  CHECK(s.list_verifications(fit_run)->empty());

  CHECK(s.put_verification({run, 5, model.id, "{}", true}).error().code == StoreErrc::not_found);
  CHECK(s.put_verification({run, 0, 999, "{}", true}).error().code == StoreErrc::not_found);
  CHECK(s.put_verification({run, 0, model.id, "", true}).error().code ==
        StoreErrc::invalid_argument);
  CHECK(s.list_verifications(999).error().code == StoreErrc::not_found);
}

TEST_CASE("store: runs left settling or running by a crash are marked interrupted",
          "[store][runs]") {
  TempDir tmp;
  const auto path = tmp / "crash.db";
  std::int64_t pending, settling, running, completed;
  {
    Store s = open_ok(path);
    pending = s.create_run(two_unit_run()).value();
    settling = s.create_run(two_unit_run()).value();
    running = s.create_run(two_unit_run()).value();
    completed = s.create_run(two_unit_run()).value();
    REQUIRE(s.set_run_state(settling, RunState::settling, "start").has_value());
    REQUIRE(s.set_run_state(running, RunState::running, "start").has_value());
    REQUIRE(s.set_run_state(completed, RunState::completed, "done").has_value());
    const SampleRow rows[] = {sample(0, 10), sample(0, 11), sample(1, 12)};
    REQUIRE(s.append_samples(running, rows).has_value());
    // The Store goes away without any state change, as in a crash.
  }
  Store s = open_ok(path);
  auto marked = s.mark_interrupted_runs("daemon restarted after a crash");
  REQUIRE(marked.has_value());
  CHECK(*marked == std::vector<std::int64_t>{settling, running});

  auto r = s.get_run(running).value();
  CHECK(r.run.state == RunState::interrupted);
  CHECK(r.run.state_reason == "daemon restarted after a crash");
  CHECK(r.run.ended_at.has_value());
  CHECK(r.events.back().kind == EventKind::state);
  CHECK(r.events.back().t_s == 12.0);  // the last sample stored
  CHECK(s.get_run(settling)->events.back().t_s.has_value() == false);
  CHECK(s.get_run(pending)->run.state == RunState::pending);
  CHECK(s.get_run(completed)->run.state == RunState::completed);
  CHECK(s.mark_interrupted_runs("again")->empty());
  CHECK(s.integrity_check().value().empty());
}

TEST_CASE("store: integrity_check reports a broken reference", "[store][schema]") {
  TempDir tmp;
  const auto path = tmp / "fk.db";
  { Store s = open_ok(path); REQUIRE(s.create_run(two_unit_run()).has_value()); }
  {
    Raw raw(path);  // foreign keys are off in a raw connection: break one behind the store's back
    raw.exec("INSERT INTO run_events (run_id, at, kind) VALUES (77, 'x', 'note')");
  }
  Store s = open_ok(path);
  auto problems = s.integrity_check();
  REQUIRE(problems.has_value());
  REQUIRE(problems->size() == 1);
  CHECK_THAT(problems->front(), Contains("run_events"));
  CHECK_THAT(problems->front(), Contains("runs"));
}

TEST_CASE("store: writes to a read-only database are errors and lose nothing",
          "[store][failure]") {
  TempDir tmp;
  const auto path = tmp / "ro.db";
  std::int64_t run;
  {
    Store s = open_ok(path);
    run = s.create_run(two_unit_run()).value();
    const SampleRow rows[] = {sample(0, 0), sample(0, 1)};
    REQUIRE(s.append_samples(run, rows).has_value());
  }
  // What a write-refusing store must do, as a list of what it did not (empty: all of it). Plain
  // code rather than CHECKs, so that a child process without privileges can run it too.
  auto refusal_failures = [&](Store& s) {
    std::vector<std::string> failed;
    auto expect = [&](bool ok, const char* what) {
      if (!ok) failed.emplace_back(what);
    };
    const SampleRow rows[] = {sample(0, 2)};
    auto w = s.append_samples(run, rows);
    expect(!w.has_value(), "append_samples refused");
    if (!w) {
      expect(w.error().code == StoreErrc::read_only, "append error code read_only");
      expect((w.error().sqlite_code & 0xff) == SQLITE_READONLY, "sqlite code SQLITE_READONLY");
      expect(w.error().message.find("append 1 samples to run 1") != std::string::npos,
             "message names the append");
      expect(w.error().message.find("readonly") != std::string::npos, "message says readonly");
    }
    auto c = s.create_run(two_unit_run());
    expect(!c && c.error().code == StoreErrc::read_only, "create_run refused as read_only");
    auto st = s.set_run_state(run, RunState::failed, "x");
    expect(!st && st.error().code == StoreErrc::read_only, "set_run_state refused as read_only");
    auto m = s.put_model({"FOG-001", run, std::nullopt, "{}", "", ""});
    expect(!m && m.error().code == StoreErrc::read_only, "put_model refused as read_only");
    // Reads still work and show everything stored before.
    auto n = s.count_samples(run);
    expect(n && *n == 2, "the 2 stored samples still read");
    auto r = s.get_run(run);
    expect(r && r->run.state == RunState::pending, "the run still reads as pending");
    return failed;
  };
  auto check_refused = [&](Store& s) {
    const auto failed = refusal_failures(s);
    for (const auto& f : failed) FAIL_CHECK("not done: " << f);
    CHECK(failed.empty());
  };

  SECTION("opened read-only") {
    OpenOptions ro;
    ro.read_only = true;
    Store s = open_ok(path, ro);
    check_refused(s);
  }
  SECTION("a file without write permission") {
    namespace fs = std::filesystem;
    fs::permissions(path, fs::perms::owner_read | fs::perms::group_read | fs::perms::others_read);
    if (::geteuid() != 0) {
      Store s = open_ok(path);
      check_refused(s);
    } else {
      // Root ignores file modes: the case runs in a child that gives up root for `nobody`
      // (uid/gid 65534), owner of the folder and the read-only file as a user would be of theirs.
      constexpr uid_t kNobody = 65534;
      for (const auto& e : fs::directory_iterator(tmp.dir))
        REQUIRE(::chown(e.path().c_str(), kNobody, kNobody) == 0);
      REQUIRE(::chown(tmp.dir.c_str(), kNobody, kNobody) == 0);
      int out[2];
      REQUIRE(::pipe(out) == 0);
      const pid_t child = ::fork();
      REQUIRE(child >= 0);
      if (child == 0) {
        ::close(out[0]);
        std::string report;
        if (::setgid(kNobody) != 0 || ::setuid(kNobody) != 0) {
          report = "could not become nobody";
        } else if (auto s = Store::open(path, {}); !s) {
          report = "open: " + s.error().message;
        } else {
          for (const auto& f : refusal_failures(*s)) report += f + "\n";
        }
        const auto written = ::write(out[1], report.data(), report.size());
        ::_exit(written == static_cast<ssize_t>(report.size()) ? 0 : 1);
      }
      ::close(out[1]);
      std::string report;
      char buf[512];
      for (ssize_t k; (k = ::read(out[0], buf, sizeof buf)) > 0;) report.append(buf, k);
      ::close(out[0]);
      int status = 0;
      REQUIRE(::waitpid(child, &status, 0) == child);
      REQUIRE(WIFEXITED(status));
      CHECK(WEXITSTATUS(status) == 0);
      INFO("the child without privileges reported:\n" << report);
      CHECK(report.empty());
      REQUIRE(::chown(tmp.dir.c_str(), 0, 0) == 0);
      for (const auto& e : fs::directory_iterator(tmp.dir))
        REQUIRE(::chown(e.path().c_str(), 0, 0) == 0);
    }
    fs::permissions(path, fs::perms::owner_read | fs::perms::owner_write);
  }
  Store s = open_ok(path);
  CHECK(s.count_samples(run).value() == 2);
  CHECK(s.integrity_check().value().empty());
}

TEST_CASE("store: a full disk is an error value, earlier data intact", "[store][failure]") {
  TempDir tmp;
  const auto path = tmp / "full.db";
  OpenOptions o;
  o.size_limit_bytes = 256 * 1024;  // room for a few thousand samples only
  Store s = open_ok(path, o);
  const auto run = s.create_run(two_unit_run()).value();

  std::int64_t stored = 0;
  std::optional<StoreError> error;
  for (int second = 0; second < 100000 && !error; ++second) {
    std::vector<SampleRow> rows;
    for (int u = 0; u < 2; ++u) rows.push_back(sample(u, second));
    if (auto r = s.append_samples(run, rows); r)
      stored += 2;
    else
      error = r.error();
  }
  REQUIRE(error.has_value());
  CHECK(error->code == StoreErrc::disk_full);
  CHECK_THAT(error->message, Contains("full"));
  CHECK(stored > 100);
  CHECK(s.count_samples(run).value() == stored);
  auto last = s.get_samples(run, 1, stored / 2 - 1, 1).value();
  CHECK(last.at(0).t_s == static_cast<double>(stored / 2 - 1));
  CHECK(s.integrity_check().value().empty());
  // The store is still usable: reads work and a small write that fits is not needed to recover.
  CHECK(s.get_run(run).has_value());
}

TEST_CASE("store: a size limit keeps a reserve for the run's end after samples filled it", "[store][failure]") {
  TempDir tmp;
  const auto path = tmp / "reserve.db";
  OpenOptions o;
  o.size_limit_bytes = 256 * 1024;
  Store s = open_ok(path, o);
  const auto run = s.create_run(two_unit_run()).value();
  REQUIRE(s.set_run_state(run, RunState::running, "started").has_value());
  int second = 0;
  for (; second < 100000; ++second) {
    std::vector<SampleRow> rows;
    for (int u = 0; u < 2; ++u) rows.push_back(sample(u, second));
    if (!s.append_samples(run, rows)) break;
  }
  REQUIRE(second < 100000);
  // Samples are refused, but the end of the run still goes in: a note and the state change.
  // Larger than a page: it needs new pages (overflow), which only the reserve has.
  const std::string note(5000, 'q');
  CHECK(s.add_event(run, EventKind::note, "{\"why\":\"" + note + "\"}").has_value());
  CHECK(s.set_run_state(run, RunState::aborted, "storage full").has_value());
  CHECK(s.get_run(run).value().run.state == RunState::aborted);
  // ... and the reserve is closed again: the second that did not fit still does not.
  const SampleRow next[] = {sample(0, second), sample(1, second)};
  auto r = s.append_samples(run, next);
  REQUIRE_FALSE(r.has_value());
  CHECK(r.error().code == StoreErrc::disk_full);
  CHECK(s.count_samples(run).value() == 2 * second);
  CHECK(s.integrity_check().value().empty());
  // The file stays within its limit once the WAL is checkpointed into it (at close).
  s = Store::open(":memory:").value();
  CHECK(std::filesystem::file_size(path) <= 256 * 1024);
}

TEST_CASE("store: a second connection reads while the first writes (WAL)", "[store][wal]") {
  TempDir tmp;
  const auto path = tmp / "wal.db";
  Store writer = open_ok(path);
  const auto run = writer.create_run(two_unit_run()).value();
  OpenOptions ro;
  ro.read_only = true;
  Store reader = open_ok(path, ro);
  for (int t = 0; t < 5; ++t) {
    const SampleRow rows[] = {sample(0, t)};
    REQUIRE(writer.append_samples(run, rows).has_value());
    CHECK(reader.count_samples(run).value() == t + 1);  // each call is committed at once
  }
  Store moved = std::move(writer);
  CHECK(moved);
  CHECK_FALSE(writer);
  CHECK(moved.count_samples(run).value() == 5);
}

TEST_CASE("store: the time since power-on is stored per sample and exported when known", "[store][power_on]") {
  TempDir tmp;
  Store s = open_ok(tmp / "power.db");
  const auto run = s.create_run(two_unit_run()).value();
  // Unit 0: power-on seen (12.5 s before the run's first sample); unit 1: never seen.
  std::vector<SampleRow> rows;
  for (int i = 0; i < 5; ++i) {
    SampleRow a = sample(0, i);
    a.since_power_on_s = 12.5 + i;
    rows.push_back(a);
    rows.push_back(sample(1, i));
  }
  REQUIRE(s.append_samples(run, rows).has_value());
  auto a = s.export_run(run, 0);
  REQUIRE(a.has_value());
  CHECK(a->since_power_on_s == std::vector<double>{12.5, 13.5, 14.5, 15.5, 16.5});
  auto b = s.export_run(run, 1);
  REQUIRE(b.has_value());
  CHECK_FALSE(b->has_power_on());  // not seen: not recorded, not guessed
  // A negative time since power-on is no time at all: the schema refuses it.
  SampleRow neg = sample(0, 10);
  neg.since_power_on_s = -1;
  const SampleRow bad[] = {neg};
  CHECK_FALSE(s.append_samples(run, bad).has_value());
}
