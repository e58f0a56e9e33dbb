// The store's migration scripts and the header checks made on open.
#include "schema.hpp"

#include <cstdio>
#include <string>

namespace fogbench::storage::detail {
namespace {

// Version 1: what a run records. Samples are keyed by (run, unit, time) WITHOUT ROWID, so a
// unit's samples lie together in time order and the key is the only index.
constexpr const char* kRecording = R"sql(
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

-- For people at the sqlite3 shell: samples with the phase by name.
CREATE VIEW sample_view AS
SELECT run_id, unit_index, t_s, wall_time, setpoint_c, chamber_c, gyro_dph, frames, t1_c, t2_c,
       CASE phase WHEN 0 THEN 'unknown' WHEN 1 THEN 'settle' WHEN 2 THEN 'hold'
                  WHEN 3 THEN 'heating' WHEN 4 THEN 'cooling' END AS phase,
       step, flags
FROM samples;
)sql";

// Version 2: fitted models, versioned per serial, and the verifications of them.
constexpr const char* kModels = R"sql(
CREATE TABLE models (
  id          INTEGER PRIMARY KEY,
  serial      TEXT NOT NULL,
  version     INTEGER NOT NULL CHECK (version >= 1),
  run_id      INTEGER REFERENCES runs (id) ON DELETE SET NULL,
  parent_id   INTEGER REFERENCES models (id),
  created_at  TEXT NOT NULL,
  model_json  TEXT NOT NULL CHECK (json_valid(model_json)),
  method      TEXT NOT NULL DEFAULT '',
  terms       TEXT NOT NULL DEFAULT '',
  UNIQUE (serial, version)
);
CREATE INDEX models_parent ON models (parent_id);

CREATE TABLE verifications (
  id           INTEGER PRIMARY KEY,
  run_id       INTEGER NOT NULL,
  unit_index   INTEGER NOT NULL,
  model_id     INTEGER NOT NULL REFERENCES models (id),
  created_at   TEXT NOT NULL,
  result_json  TEXT NOT NULL CHECK (json_valid(result_json)),
  pass         INTEGER NOT NULL CHECK (pass IN (0, 1)),
  FOREIGN KEY (run_id, unit_index) REFERENCES run_units (run_id, unit_index) ON DELETE CASCADE
);
CREATE INDEX verifications_run ON verifications (run_id);
CREATE INDEX verifications_model ON verifications (model_id);
)sql";

// Version 3: the time since each gyro's power-on, per sample (NULL: the daemon did not see
// it; every sample recorded before version 3). The view shows it too.
constexpr const char* kPowerOn = R"sql(
ALTER TABLE samples ADD COLUMN since_power_on_s REAL CHECK (since_power_on_s >= 0);
DROP VIEW sample_view;
CREATE VIEW sample_view AS
SELECT run_id, unit_index, t_s, wall_time, setpoint_c, chamber_c, gyro_dph, frames, t1_c, t2_c,
       CASE phase WHEN 0 THEN 'unknown' WHEN 1 THEN 'settle' WHEN 2 THEN 'hold'
                  WHEN 3 THEN 'heating' WHEN 4 THEN 'cooling' END AS phase,
       step, flags, since_power_on_s
FROM samples;
)sql";

// Version 4 (issue 13): each run's identity (station, operator, software, the hashes of its
// configuration and profile), each unit's power-on as the run saw it, and the certificates
// issued per serial with their SHA-256. Plain tables with one fact per column, so that a
// replica (PostgreSQL) takes them as they are.
constexpr const char* kIdentity = R"sql(
CREATE TABLE run_identity (
  run_id            INTEGER PRIMARY KEY REFERENCES runs (id) ON DELETE CASCADE,
  station_id        TEXT NOT NULL DEFAULT '',
  operator          TEXT NOT NULL DEFAULT '',
  operator_source   TEXT NOT NULL DEFAULT 'none'
                    CHECK (operator_source IN ('client', 'peer', 'import', 'none')),
  software_version  TEXT NOT NULL,
  git_hash          TEXT NOT NULL,
  config_sha256     TEXT NOT NULL,
  profile_sha256    TEXT NOT NULL
);

CREATE TABLE run_unit_identity (
  run_id            INTEGER NOT NULL,
  unit_index        INTEGER NOT NULL,
  powered_on_at     TEXT,
  since_power_on_s  REAL CHECK (since_power_on_s >= 0),
  PRIMARY KEY (run_id, unit_index),
  FOREIGN KEY (run_id, unit_index) REFERENCES run_units (run_id, unit_index) ON DELETE CASCADE
) WITHOUT ROWID;

CREATE TABLE certificates (
  id             INTEGER PRIMARY KEY,
  serial         TEXT NOT NULL,
  model_id       INTEGER NOT NULL REFERENCES models (id),
  model_version  INTEGER NOT NULL,
  sha256         TEXT NOT NULL CHECK (length(sha256) = 64),
  json           TEXT NOT NULL CHECK (json_valid(json)),
  created_at     TEXT NOT NULL
);
CREATE INDEX certificates_serial ON certificates (serial);
CREATE INDEX certificates_sha256 ON certificates (sha256);
)sql";

// Version 5: the daemon's live compensated rate per sample, deg/h (NULL: no model, the
// compensator warming up or its inputs missing; every sample recorded before version 5).
constexpr const char* kLiveCompensation = R"sql(
ALTER TABLE samples ADD COLUMN compensated_dph REAL;
DROP VIEW sample_view;
CREATE VIEW sample_view AS
SELECT run_id, unit_index, t_s, wall_time, setpoint_c, chamber_c, gyro_dph, frames, t1_c, t2_c,
       CASE phase WHEN 0 THEN 'unknown' WHEN 1 THEN 'settle' WHEN 2 THEN 'hold'
                  WHEN 3 THEN 'heating' WHEN 4 THEN 'cooling' END AS phase,
       step, flags, since_power_on_s, compensated_dph
FROM samples;
)sql";

// Version 6: qualification plans (docs/plans.md). A plan is queued (queue_pos gives the order)
// or running, then completed, aborted or failed; progress_json is the daemon's plan runner's
// whole state (the step it is in, its runs, each unit's measurements and verdict), rewritten at
// each change so a restart resumes where it stood. plan_events is the audit trail of plans and
// of the queue (plan_id NULL: about no one plan).
constexpr const char* kPlans = R"sql(
CREATE TABLE plans (
  id            INTEGER PRIMARY KEY,
  name          TEXT NOT NULL,
  source        TEXT NOT NULL,
  plan_text     TEXT NOT NULL,
  units_json    TEXT NOT NULL CHECK (json_valid(units_json)),
  state         TEXT NOT NULL CHECK (state IN ('queued', 'running', 'completed', 'aborted', 'failed')),
  queue_pos     INTEGER,
  created_at    TEXT NOT NULL,
  started_at    TEXT,
  ended_at      TEXT,
  reason        TEXT NOT NULL DEFAULT '',
  progress_json TEXT NOT NULL DEFAULT '{}' CHECK (json_valid(progress_json))
);
CREATE INDEX plans_state ON plans (state, queue_pos);
CREATE TABLE plan_events (
  id          INTEGER PRIMARY KEY,
  at          TEXT NOT NULL,
  plan_id     INTEGER REFERENCES plans (id),
  kind        TEXT NOT NULL,
  detail_json TEXT NOT NULL DEFAULT '{}' CHECK (json_valid(detail_json))
);
CREATE INDEX plan_events_plan ON plan_events (plan_id);
)sql";

// Version 7 (issue 14, the plant): a unit's optional lot id, and the outbox of runs waiting to be
// replicated to the plant's PostgreSQL (fogbench::plant). A row per queuing: sent_at is set
// once the plant has committed the run; a run queued again (re-sent) gets a new row. Rows are
// taken in id order, so the plant receives runs in the order they completed.
constexpr const char* kPlant = R"sql(
ALTER TABLE run_units ADD COLUMN lot TEXT CHECK (lot IS NULL OR length(lot) BETWEEN 1 AND 64);
CREATE INDEX run_units_lot ON run_units (lot) WHERE lot IS NOT NULL;
CREATE TABLE plant_outbox (
  id               INTEGER PRIMARY KEY,
  run_id           INTEGER NOT NULL REFERENCES runs (id) ON DELETE CASCADE,
  queued_at        TEXT NOT NULL,
  attempts         INTEGER NOT NULL DEFAULT 0,
  last_error       TEXT NOT NULL DEFAULT '',
  last_attempt_at  TEXT,
  sent_at          TEXT
);
CREATE INDEX plant_outbox_pending ON plant_outbox (id) WHERE sent_at IS NULL;
CREATE INDEX plant_outbox_run ON plant_outbox (run_id);
)sql";

// Version 8 (issue 24, one verdict per serial): every verdict decided, by one rule (a plan's
// limits or the analysis settings), with what it judged; the serial's verdict is its latest row.
constexpr const char* kVerdicts = R"sql(
CREATE TABLE verdicts (
  id            INTEGER PRIMARY KEY,
  serial        TEXT NOT NULL,
  run_id        INTEGER NOT NULL REFERENCES runs (id) ON DELETE CASCADE,
  unit_index    INTEGER NOT NULL,
  model_id      INTEGER REFERENCES models (id),
  verdict       TEXT NOT NULL CHECK (verdict IN ('pass', 'marginal', 'fail', 'incomplete')),
  rule          TEXT NOT NULL CHECK (rule IN ('plan', 'analysis')),
  plan_id       INTEGER REFERENCES plans (id),
  plan_name     TEXT NOT NULL DEFAULT '',
  plan_sha256   TEXT NOT NULL DEFAULT '',
  limits_json   TEXT NOT NULL DEFAULT '[]' CHECK (json_valid(limits_json)),
  reasons_json  TEXT NOT NULL DEFAULT '[]' CHECK (json_valid(reasons_json)),
  decided_at    TEXT NOT NULL,
  CHECK ((rule = 'plan') = (plan_id IS NOT NULL)),
  FOREIGN KEY (run_id, unit_index) REFERENCES run_units (run_id, unit_index) ON DELETE CASCADE
);
CREATE INDEX verdicts_serial ON verdicts (serial, id);
CREATE INDEX verdicts_run ON verdicts (run_id);
)sql";

// Version 9 (issue 24, traceability): who started a plan and the lot of each of its units,
// given to every run the plan starts (operator and operator_source as in runs; lots_json is
// {serial: lot}, a unit without a lot left out).
constexpr const char* kPlanTraceability = R"sql(
ALTER TABLE plans ADD COLUMN operator TEXT NOT NULL DEFAULT '';
ALTER TABLE plans ADD COLUMN operator_source TEXT NOT NULL DEFAULT 'none'
  CHECK (operator_source IN ('client', 'peer', 'import', 'none'));
ALTER TABLE plans ADD COLUMN lots_json TEXT NOT NULL DEFAULT '{}' CHECK (json_valid(lots_json));
)sql";

// Version 10 (issue 24, bench slots): the fixture position (the configuration's slot name) each
// unit of a run sat in, so that a resumed run reads the same CAN node and thermistors; NULL for
// runs recorded before. A plan's slots_json is {serial: slot}, given to every run it starts.
constexpr const char* kUnitSlots = R"sql(
ALTER TABLE run_units ADD COLUMN slot TEXT CHECK (slot IS NULL OR length(slot) BETWEEN 1 AND 16);
ALTER TABLE plans ADD COLUMN slots_json TEXT NOT NULL DEFAULT '{}' CHECK (json_valid(slots_json));
)sql";

// Version 11 (issue 28, retention): a run whose samples `fogctl store prune` deleted keeps its
// record with when and how many (Store::prune, docs/storage.md "Retention").
constexpr const char* kPrunedRuns = R"sql(
ALTER TABLE runs ADD COLUMN pruned_at TEXT;
ALTER TABLE runs ADD COLUMN pruned_samples INTEGER NOT NULL DEFAULT 0 CHECK (pruned_samples >= 0);
)sql";

// Version 12 (issue 29, the rate table): the rate the daemon commanded the rate table to at each
// second, deg/s (NULL: the run drove no table; every sample recorded before version 12), so that
// a run's export gives the rate-sequence columns `fogctl scale-factor` reads.
constexpr const char* kTableRate = R"sql(
ALTER TABLE samples ADD COLUMN rate_in_dps REAL;
DROP VIEW sample_view;
CREATE VIEW sample_view AS
SELECT run_id, unit_index, t_s, wall_time, setpoint_c, chamber_c, gyro_dph, frames, t1_c, t2_c,
       CASE phase WHEN 0 THEN 'unknown' WHEN 1 THEN 'settle' WHEN 2 THEN 'hold'
                  WHEN 3 THEN 'heating' WHEN 4 THEN 'cooling' END AS phase,
       step, flags, since_power_on_s, compensated_dph, rate_in_dps
FROM samples;
)sql";

// Version 13 (issue 29, three-axis units): the y and z outputs of a three-axis unit per second,
// deg/h (gyro_dph stays axis 0, x), and how many axes each run unit has. Nullable columns on
// samples rather than a side table: a one-axis row stores them as two NULLs (a byte each in the
// record header, nothing in its body) and is read by the same single range scan of the primary
// key as before; a side table would cost three-axis runs a second B-tree insert per second and
// every read a join or a second scan (docs/storage.md "Three-axis units").
constexpr const char* kAxes = R"sql(
ALTER TABLE samples ADD COLUMN gyro_y_dph REAL;
ALTER TABLE samples ADD COLUMN gyro_z_dph REAL;
ALTER TABLE run_units ADD COLUMN axes INTEGER NOT NULL DEFAULT 1 CHECK (axes IN (1, 3));
DROP VIEW sample_view;
CREATE VIEW sample_view AS
SELECT run_id, unit_index, t_s, wall_time, setpoint_c, chamber_c, gyro_dph, frames, t1_c, t2_c,
       CASE phase WHEN 0 THEN 'unknown' WHEN 1 THEN 'settle' WHEN 2 THEN 'hold'
                  WHEN 3 THEN 'heating' WHEN 4 THEN 'cooling' END AS phase,
       step, flags, since_power_on_s, compensated_dph, rate_in_dps, gyro_y_dph, gyro_z_dph
FROM samples;
)sql";

// Version 14 (issue 29, three-axis units): per-axis models and verdicts. A model's axis ('x',
// 'y' or 'z' for a three-axis unit's; NULL for a one-axis unit's, which is every model stored
// before: the x axis, the only one such a unit has), and with a three-axis unit's verdict the
// evidence of each axis it was the worst of (a JSON array; NULL for a one-axis unit's verdict).
// Versions stay numbered per serial across its axes.
constexpr const char* kAxisModels = R"sql(
ALTER TABLE models ADD COLUMN axis TEXT CHECK (axis IS NULL OR axis IN ('x', 'y', 'z'));
CREATE INDEX models_serial_axis ON models (serial, axis, version);
ALTER TABLE verdicts ADD COLUMN axes_json TEXT CHECK (axes_json IS NULL OR json_valid(axes_json));
)sql";

// Version 15 (issue 29, three-axis units): a three-axis unit whose axes have their own coil
// thermistors, y's and z's centre and outer wall per second, degC (t1_c, t2_c are then x's).
// Nullable columns as version 13's: a row without them (every one-axis unit's, a three-axis
// unit's whose axes share t1_c, t2_c, every sample recorded before version 15) stores four NULLs
// in its record header and nothing in its body.
constexpr const char* kAxisThermistors = R"sql(
ALTER TABLE samples ADD COLUMN t1_y_c REAL;
ALTER TABLE samples ADD COLUMN t2_y_c REAL;
ALTER TABLE samples ADD COLUMN t1_z_c REAL;
ALTER TABLE samples ADD COLUMN t2_z_c REAL;
DROP VIEW sample_view;
CREATE VIEW sample_view AS
SELECT run_id, unit_index, t_s, wall_time, setpoint_c, chamber_c, gyro_dph, frames, t1_c, t2_c,
       CASE phase WHEN 0 THEN 'unknown' WHEN 1 THEN 'settle' WHEN 2 THEN 'hold'
                  WHEN 3 THEN 'heating' WHEN 4 THEN 'cooling' END AS phase,
       step, flags, since_power_on_s, compensated_dph, rate_in_dps, gyro_y_dph, gyro_z_dph,
       t1_y_c, t2_y_c, t1_z_c, t2_z_c
FROM samples;
)sql";

constexpr Migration kMigrations[] = {
    {1, "recording tables", kRecording},
    {2, "models and verifications", kModels},
    {3, "time since power-on", kPowerOn},
    {4, "run identity and certificates", kIdentity},
    {5, "live compensated rate", kLiveCompensation},
    {6, "qualification plans and their queue", kPlans},
    {7, "unit lots and the plant outbox", kPlant},
    {8, "one verdict per serial", kVerdicts},
    {9, "plan operator and unit lots", kPlanTraceability},
    {10, "unit slots", kUnitSlots},
    {11, "pruned runs", kPrunedRuns},
    {12, "commanded table rate", kTableRate},
    {13, "three-axis units", kAxes},
    {14, "per-axis models and verdicts", kAxisModels},
    {15, "per-axis thermistors", kAxisThermistors},
};

StoreResult<std::int64_t> query_int(Database& db, const std::string& sql, std::string_view what) {
  sqlite3_stmt* stmt = nullptr;
  int rc = sqlite3_prepare_v2(db.handle(), sql.c_str(), -1, &stmt, nullptr);
  if (rc != SQLITE_OK) return std::unexpected(db.error(rc, what));
  rc = sqlite3_step(stmt);
  std::int64_t value = 0;
  if (rc == SQLITE_ROW) value = sqlite3_column_int64(stmt, 0);
  const bool ok = rc == SQLITE_ROW || rc == SQLITE_DONE;
  auto err = ok ? StoreError{} : db.error(rc, what);
  sqlite3_finalize(stmt);
  if (!ok) return std::unexpected(std::move(err));
  return value;
}

}  // namespace

std::span<const Migration> migrations() { return kMigrations; }
int current_version() { return kMigrations[std::size(kMigrations) - 1].version; }

StoreResult<int> inspect_schema(Database& db) {
  // The first read of the header: a file that is not a database fails here, untouched.
  auto app = query_int(db, "PRAGMA application_id", "read the header");
  if (!app) return std::unexpected(app.error());
  auto version = query_int(db, "PRAGMA user_version", "read the schema version");
  if (!version) return std::unexpected(version.error());
  auto objects = query_int(db, "SELECT count(*) FROM sqlite_schema", "read the schema");
  if (!objects) return std::unexpected(objects.error());

  const std::string name = "'" + db.path().string() + "'";
  if (*app != 0 && *app != kApplicationId) {
    char id[16];
    std::snprintf(id, sizeof id, "0x%08llX", static_cast<unsigned long long>(*app & 0xFFFFFFFF));
    return std::unexpected(db.error(
        StoreErrc::not_fogbench,
        "refusing a SQLite database of another application (application_id " +
            std::string(id) + ")"));
  }
  // Every fogbench version stamps application_id in its first migration, so tables without
  // it belong to someone else.
  if (*app == 0 && (*objects != 0 || *version != 0))
    return std::unexpected(db.error(StoreErrc::not_fogbench,
                                    "refusing a SQLite database that is not a fogbench store "
                                    "(it has tables but no fogbench application_id)"));
  if (*version > current_version())
    return std::unexpected(db.error(
        StoreErrc::schema_too_new,
        "schema version " + std::to_string(*version) + " is newer than this fogbench knows (" +
            std::to_string(current_version()) +
            "); it was written by a newer fogbench: use that, this one will not touch it"));
  return static_cast<int>(*version);
}

StoreResult<int> migrate(Database& db, int from_version) {
  int version = from_version;
  for (const Migration& m : kMigrations) {
    if (m.version <= version) continue;
    const std::string what = "migrate schema " + std::to_string(m.version - 1) + " -> " +
                             std::to_string(m.version) + " (" + std::string(m.what) + ")";
    Transaction tx(db);
    if (auto ok = tx.begin(what); !ok) return std::unexpected(ok.error());
    // Another process may have migrated while this one waited for the write lock.
    auto now = query_int(db, "PRAGMA user_version", what);
    if (!now) return std::unexpected(now.error());
    if (*now >= m.version) {
      version = static_cast<int>(*now);
      continue;  // the transaction rolls back: nothing was written
    }
    auto fail = [&](StoreError e) {
      e.code = e.code == StoreErrc::sqlite ? StoreErrc::migration_failed : e.code;
      return std::unexpected(std::move(e));
    };
    if (auto ok = db.exec(m.sql, what); !ok) return fail(ok.error());
    if (auto ok = db.exec("PRAGMA user_version = " + std::to_string(m.version), what); !ok)
      return fail(ok.error());
    if (m.version == 1) {
      if (auto ok = db.exec("PRAGMA application_id = " + std::to_string(kApplicationId), what);
          !ok)
        return fail(ok.error());
    }
    if (auto ok = tx.commit(what); !ok) return fail(ok.error());
    version = m.version;
  }
  return version;
}

}  // namespace fogbench::storage::detail
