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
#include "fogbench/storage/errors.hpp"
#include "fogbench/storage/identity.hpp"
#include "fogbench/storage/models.hpp"
#include "fogbench/storage/runs.hpp"
#include "fogbench/storage/samples.hpp"
#include "fogbench/storage/store.hpp"
#include "store_fixture.hpp"

using namespace fogbench;
using namespace fogbench::storage;
using Catch::Matchers::Contains;

using namespace fogbench::storage::testing;

namespace {


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
    CHECK(Store::current_schema_version() >= 7);  // 4 identity, 5 live compensation, 6 plans, 7 lots and outbox
    CHECK(s.path() == path);
  }
  Raw raw(path);
  CHECK(raw.text("PRAGMA journal_mode") == "wal");
  CHECK(raw.integer("PRAGMA user_version") == Store::current_schema_version());
  CHECK(raw.integer("PRAGMA application_id") == 0x464F4742);
  for (const char* table : {"runs", "run_units", "samples", "run_events", "models", "verifications",
                            "run_identity", "run_unit_identity", "certificates",
                            "plans", "plan_events"})
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
    // A run from before version 4 has no identity: it says so.
    CHECK_FALSE(s.get_run_identity(7).value().has_value());
    // A unit from before version 7 has no lot.
    CHECK_FALSE(s.get_run(7)->run.units.at(0).lot.has_value());
    // Samples from before version 3 have no time since power-on, and from before version 5 no
    // live compensation: the export says not recorded.
    auto old = s.export_run(7, 0);
    REQUIRE(old.has_value());
    CHECK_FALSE(old->has_power_on());
    CHECK_FALSE(old->has_compensated());
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

TEST_CASE("store: a migration first backs the file up as it was, the way back to the older fogbench", "[store][schema]") {
  TempDir tmp;
  const auto path = tmp / "v1.db";
  const auto backup = tmp / "v1.db.schema-1.bak";
  auto make_v1 = [&](int samples) {
    std::filesystem::remove(path);
    Raw raw(path);
    raw.exec(kSchemaV1);
    raw.exec("INSERT INTO runs (id, created_at, profile_name, purpose, state) "
             "VALUES (7, '2026-01-01T00:00:00.000Z', 'old', 'fit', 'completed');"
             "INSERT INTO run_units VALUES (7, 0, 'FOG-OLD');");
    for (int t = 0; t < samples; ++t)
      raw.exec("INSERT INTO samples (run_id, unit_index, t_s, gyro_dph, t1_c, t2_c) VALUES (7, 0, " +
               std::to_string(t) + ", 0.5, 20, 21)");
    ::chmod(path.c_str(), 0600);
  };
  SECTION("the backup holds version 1 and every row, with the store's mode") {
    make_v1(3);
    { Store s = open_ok(path); CHECK(s.schema_version() == Store::current_schema_version()); }
    REQUIRE(std::filesystem::exists(backup));
    Raw old(backup);
    CHECK(old.integer("PRAGMA user_version") == 1);
    CHECK(old.integer("SELECT count(*) FROM samples") == 3);
    CHECK(old.integer("SELECT count(*) FROM sqlite_schema WHERE name = 'models'") == 0);
    CHECK((std::filesystem::status(backup).permissions() & std::filesystem::perms::all) ==
          (std::filesystem::perms::owner_read | std::filesystem::perms::owner_write));
    // Opening the migrated store again makes no new backup (nothing to migrate).
    std::filesystem::remove(backup);
    { Store s = open_ok(path); }
    CHECK_FALSE(std::filesystem::exists(backup));
  }
  SECTION("an older backup of the same version is replaced by the newer file's") {
    make_v1(1);
    { Store s = open_ok(path); }
    make_v1(5);  // restored and written to by the older fogbench, then upgraded again
    { Store s = open_ok(path); }
    Raw old(backup);
    CHECK(old.integer("SELECT count(*) FROM samples") == 5);
  }
  SECTION("a backup that cannot be made refuses the migration and leaves the file as it was") {
    make_v1(2);
    std::filesystem::create_directories(backup / "in-the-way");  // rename onto it fails
    auto s = Store::open(path);
    REQUIRE_FALSE(s.has_value());
    CHECK(s.error().code == StoreErrc::migration_failed);
    CHECK_THAT(s.error().message, Contains("cannot back up '" + path.string() + "'"));
    CHECK_THAT(s.error().message, Contains("schema 1 -> " + std::to_string(Store::current_schema_version())));
    CHECK_THAT(s.error().message, Contains("the store was not migrated"));
    Raw raw(path);
    CHECK(raw.integer("PRAGMA user_version") == 1);
    CHECK(raw.integer("SELECT count(*) FROM samples") == 2);
    // No temporary copy is left beside it.
    for (const auto& e : std::filesystem::directory_iterator(tmp.dir))
      CHECK(e.path().filename().string().find(".tmp-") == std::string::npos);
  }
  SECTION("without a backup when asked (OpenOptions::backup_before_migration = false)") {
    make_v1(1);
    OpenOptions o;
    o.backup_before_migration = false;
    auto s = Store::open(path, o);
    REQUIRE(s.has_value());
    CHECK_FALSE(std::filesystem::exists(backup));
  }
}

TEST_CASE("store: an old file that cannot be written is refused at upgrade, named, untouched", "[store][schema][failure]") {
  namespace fs = std::filesystem;
  TempDir tmp;
  const auto path = tmp / "v1ro.db";
  {
    Raw raw(path);
    raw.exec(kSchemaV1);
    raw.exec("INSERT INTO runs (id, created_at, profile_name, purpose, state) "
             "VALUES (7, '2026-01-01T00:00:00.000Z', 'old', 'fit', 'completed');");
  }
  fs::permissions(path, fs::perms::owner_read | fs::perms::group_read | fs::perms::others_read);
  // What the open said, as one line ("ok" when it opened). Root ignores file modes: as root the
  // open runs in a child that gives up root for `nobody` (uid/gid 65534), owner of the folder
  // and the file as a user would be of theirs (as store_failure_test does).
  auto attempt = [&]() -> std::string {
    auto s = Store::open(path);
    if (s) return "ok";
    return std::string(to_string(s.error().code)) + ": " + s.error().message;
  };
  std::string said;
  if (::geteuid() != 0) {
    said = attempt();
  } else {
    constexpr uid_t kNobody = 65534;
    REQUIRE(::chown(path.c_str(), kNobody, kNobody) == 0);
    REQUIRE(::chown(tmp.dir.c_str(), kNobody, kNobody) == 0);
    int out[2];
    REQUIRE(::pipe(out) == 0);
    const pid_t child = ::fork();
    REQUIRE(child >= 0);
    if (child == 0) {
      ::close(out[0]);
      const std::string report =
          (::setgid(kNobody) != 0 || ::setuid(kNobody) != 0) ? "could not become nobody" : attempt();
      const auto written = ::write(out[1], report.data(), report.size());
      ::_exit(written == static_cast<ssize_t>(report.size()) ? 0 : 1);
    }
    ::close(out[1]);
    char buf[1024];
    for (ssize_t k; (k = ::read(out[0], buf, sizeof buf)) > 0;) said.append(buf, static_cast<std::size_t>(k));
    ::close(out[0]);
    int status = 0;
    REQUIRE(::waitpid(child, &status, 0) == child);
    CHECK(WIFEXITED(status));
    REQUIRE(::chown(tmp.dir.c_str(), 0, 0) == 0);
    REQUIRE(::chown(path.c_str(), 0, 0) == 0);
  }
  INFO(said);
  CHECK(said.starts_with("read_only: "));
  CHECK_THAT(said, Contains("schema version 1 needs migrating to " + std::to_string(Store::current_schema_version())));
  CHECK_THAT(said, Contains("read-only; nothing was changed"));
  CHECK_THAT(said, Contains(path.string()));
  fs::permissions(path, fs::perms::owner_read | fs::perms::owner_write);
  Raw raw(path);
  CHECK(raw.integer("PRAGMA user_version") == 1);
  CHECK(raw.text("PRAGMA journal_mode") != "wal");  // not even switched to WAL
  CHECK(raw.integer("SELECT count(*) FROM runs") == 1);
  CHECK_FALSE(fs::exists(tmp / "v1ro.db.schema-1.bak"));
}

TEST_CASE("store: newer, foreign and non-database files are refused untouched", "[store][schema]") {
  TempDir tmp;
  SECTION("a newer schema version") {
    const auto path = tmp / "future.db";
    {
      Raw raw(path);
      raw.exec("CREATE TABLE runs (id INTEGER PRIMARY KEY, future_column TEXT);"
               "PRAGMA user_version = 99; PRAGMA application_id = 1179600706;");
    }
    auto s = Store::open(path);
    REQUIRE_FALSE(s.has_value());
    CHECK(s.error().code == StoreErrc::schema_too_new);
    CHECK_THAT(s.error().message, Contains("schema version 99 is newer"));
    CHECK_THAT(s.error().message, Contains(path.string()));
    Raw raw(path);
    CHECK(raw.integer("PRAGMA user_version") == 99);
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

TEST_CASE("store: the live compensated rate is stored per sample, exported and imported when any, NULL before it", "[store][compensated]") {
  TempDir tmp;
  Store s = open_ok(tmp / "live.db");
  const auto run = s.create_run(two_unit_run()).value();
  // Unit 0: warming up for 2 samples, then compensated; unit 1: no model, none at all.
  std::vector<SampleRow> rows;
  for (int i = 0; i < 5; ++i) {
    SampleRow a = sample(0, i);
    if (i >= 2) a.compensated_dph = 0.25 * i;
    rows.push_back(a);
    rows.push_back(sample(1, i));
  }
  REQUIRE(s.append_samples(run, rows).has_value());
  auto got = s.get_samples(run, 0, 0, 10);
  REQUIRE(got.has_value());
  REQUIRE(got->size() == 5);
  CHECK(std::isnan(got->at(1).compensated_dph));
  CHECK(got->at(2).compensated_dph == 0.5);
  auto a = s.export_run(run, 0, {.include_settle = true});
  REQUIRE(a.has_value());
  REQUIRE(a->compensated_dph.size() == 5);
  CHECK(std::isnan(a->compensated_dph[0]));
  CHECK(a->compensated_dph[4] == 1.0);
  auto b = s.export_run(run, 1, {.include_settle = true});
  REQUIRE(b.has_value());
  CHECK_FALSE(b->has_compensated());
  // Imported back (a CSV of an export): the column comes with it.
  auto imported = s.import_run(*a, ImportOptions{.serial = "FOG-X", .profile_text = {}, .identity = {}, .lot = {}});
  REQUIRE(imported.has_value());
  auto again = s.export_run(*imported, 0, {.include_settle = true});
  REQUIRE(again.has_value());
  REQUIRE(again->compensated_dph.size() == 5);
  CHECK(again->compensated_dph[3] == 0.75);
  CHECK(std::isnan(again->compensated_dph[1]));
}
