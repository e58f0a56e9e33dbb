// The plant's PostgreSQL schema and its migrations, versioned like the bench's SQLite one
// (storage/src/schema.cpp): fogbench.schema_version holds one row per applied migration.
//
// Everything lives in the schema `fogbench`. Every table is keyed by (bench_id, run_id, ...):
// a bench's own ids are unique only on that bench. Later migrations add what other parts
// bring: version 2 adds the run identity (keyed the same way, with ON DELETE CASCADE from
// fogbench.runs, so that a re-sent run replaces it too), the certificates and each sample's
// compensated rate; version 3 the stations' public keys (station_keys); version 4 the verdicts;
// version 5 the rate table's commanded rate, the y and z axes and each unit's axes; version 6 a
// three-axis unit's per-axis models and verdicts (models.axis, verdicts.axes_json); version 7 its
// coil thermistors per axis (samples.t1_y_c .. t2_z_c).
#include <libpq-fe.h>

#include "fogbench/plant/plant.hpp"
#include "pg.hpp"

namespace fogbench::plant {
namespace {

struct Migration {
  int version;
  const char* what;
  const char* sql;
};

// Version 1: runs, units (serial, lot), samples, events, models, verifications, and the figures
// the fleet statistics read (one number per row: a model's coefficients, a verification's
// figures). Samples carry no foreign key: a key checked per row would halve the COPY's rate,
// and replication deletes them by (bench_id, run_id) itself.
constexpr const char* kV1 = R"sql(
CREATE TABLE fogbench.runs (
  bench_id      text NOT NULL,
  run_id        bigint NOT NULL,
  created_at    timestamptz NOT NULL,
  profile_name  text NOT NULL,
  purpose       text NOT NULL CHECK (purpose IN ('fit', 'verify')),
  state         text NOT NULL,
  state_reason  text NOT NULL DEFAULT '',
  config_json   jsonb NOT NULL DEFAULT '{}',
  started_at    timestamptz,
  ended_at      timestamptz,
  time_scale    double precision NOT NULL DEFAULT 1,
  replicated_at timestamptz NOT NULL DEFAULT now(),
  PRIMARY KEY (bench_id, run_id)
);
CREATE INDEX runs_ended ON fogbench.runs (ended_at);

CREATE TABLE fogbench.units (
  bench_id    text NOT NULL,
  run_id      bigint NOT NULL,
  unit_index  integer NOT NULL CHECK (unit_index >= 0),
  serial      text NOT NULL,
  lot         text,
  PRIMARY KEY (bench_id, run_id, unit_index),
  FOREIGN KEY (bench_id, run_id) REFERENCES fogbench.runs ON DELETE CASCADE
);
CREATE INDEX units_serial ON fogbench.units (serial);
CREATE INDEX units_lot ON fogbench.units (lot);

CREATE TABLE fogbench.samples (
  bench_id          text NOT NULL,
  run_id            bigint NOT NULL,
  unit_index        integer NOT NULL,
  t_s               double precision NOT NULL,
  wall_time         double precision,
  setpoint_c        double precision,
  chamber_c         double precision,
  gyro_dph          double precision,
  frames            bigint,
  t1_c              double precision,
  t2_c              double precision,
  phase             smallint,
  step              integer,
  flags             smallint,
  since_power_on_s  double precision,
  PRIMARY KEY (bench_id, run_id, unit_index, t_s)
);

CREATE TABLE fogbench.events (
  bench_id  text NOT NULL,
  run_id    bigint NOT NULL,
  event_id  bigint NOT NULL,
  t_s       double precision,
  at        timestamptz NOT NULL,
  kind      text NOT NULL,
  detail    jsonb NOT NULL DEFAULT '{}',
  PRIMARY KEY (bench_id, run_id, event_id),
  FOREIGN KEY (bench_id, run_id) REFERENCES fogbench.runs ON DELETE CASCADE
);

CREATE TABLE fogbench.models (
  bench_id    text NOT NULL,
  model_id    bigint NOT NULL,
  run_id      bigint NOT NULL,
  unit_index  integer,
  serial      text NOT NULL,
  version     integer NOT NULL,
  parent_id   bigint,
  created_at  timestamptz NOT NULL,
  method      text NOT NULL DEFAULT '',
  terms       text NOT NULL DEFAULT '',
  model_json  jsonb NOT NULL,
  PRIMARY KEY (bench_id, model_id),
  FOREIGN KEY (bench_id, run_id) REFERENCES fogbench.runs ON DELETE CASCADE
);
CREATE INDEX models_serial ON fogbench.models (serial);

CREATE TABLE fogbench.verifications (
  bench_id         text NOT NULL,
  verification_id  bigint NOT NULL,
  run_id           bigint NOT NULL,
  unit_index       integer NOT NULL,
  model_id         bigint NOT NULL,
  created_at       timestamptz NOT NULL,
  pass             boolean NOT NULL,
  verdict          text,
  result_json      jsonb NOT NULL,
  PRIMARY KEY (bench_id, verification_id),
  FOREIGN KEY (bench_id, run_id) REFERENCES fogbench.runs ON DELETE CASCADE
);

CREATE TABLE fogbench.figures (
  bench_id    text NOT NULL,
  run_id      bigint NOT NULL,
  unit_index  integer NOT NULL,
  source      text NOT NULL CHECK (source IN ('model', 'verification')),
  source_id   bigint NOT NULL,
  name        text NOT NULL,
  value       double precision NOT NULL,
  PRIMARY KEY (bench_id, source, source_id, name),
  FOREIGN KEY (bench_id, run_id) REFERENCES fogbench.runs ON DELETE CASCADE
);
CREATE INDEX figures_name ON fogbench.figures (name, bench_id, run_id);
)sql";

// Version 2: what issue 13 and the live compensation added to the bench. The run's identity and
// its units' power-on, replaced with the run (ON DELETE CASCADE); certificates belong to a
// serial, not to a run (immutable: no foreign key, inserted once, never deleted by a re-send);
// each sample's compensated rate (deg/h, NULL when the daemon computed none). A certificate's
// JSON is text, not jsonb: its sha256 is of those exact bytes (jsonb would reorder the keys).
constexpr const char* kV2 = R"sql(
ALTER TABLE fogbench.samples ADD COLUMN compensated_dph double precision;

CREATE TABLE fogbench.run_identity (
  bench_id          text NOT NULL,
  run_id            bigint NOT NULL,
  station_id        text NOT NULL DEFAULT '',
  operator          text NOT NULL DEFAULT '',
  operator_source   text NOT NULL DEFAULT 'none',
  software_version  text NOT NULL,
  git_hash          text NOT NULL,
  config_sha256     text NOT NULL,
  profile_sha256    text NOT NULL,
  PRIMARY KEY (bench_id, run_id),
  FOREIGN KEY (bench_id, run_id) REFERENCES fogbench.runs ON DELETE CASCADE
);
CREATE INDEX run_identity_station ON fogbench.run_identity (station_id);
CREATE INDEX run_identity_operator ON fogbench.run_identity (operator);

CREATE TABLE fogbench.unit_identity (
  bench_id          text NOT NULL,
  run_id            bigint NOT NULL,
  unit_index        integer NOT NULL CHECK (unit_index >= 0),
  powered_on_at     timestamptz,
  since_power_on_s  double precision,
  PRIMARY KEY (bench_id, run_id, unit_index),
  FOREIGN KEY (bench_id, run_id) REFERENCES fogbench.runs ON DELETE CASCADE
);

CREATE TABLE fogbench.certificates (
  bench_id        text NOT NULL,
  certificate_id  bigint NOT NULL,
  serial          text NOT NULL,
  model_id        bigint NOT NULL,
  model_version   integer NOT NULL,
  sha256          text NOT NULL,
  json            text NOT NULL,
  created_at      timestamptz NOT NULL,
  PRIMARY KEY (bench_id, certificate_id)
);
CREATE INDEX certificates_serial ON fogbench.certificates (serial);
CREATE INDEX certificates_sha256 ON fogbench.certificates (sha256);
)sql";

// Version 3 (issue 24): each station's public keys, the plant's keyring for checking the
// certificates its benches signed. Filled as certificates replicate (the signing key's public
// half travels in each certificate's signed_by, its id checked against it); first_seen is the
// oldest such certificate's date. revoked_at is the plant's to set (docs/plant.md "Station
// keys"): a key revoked from that time on.
constexpr const char* kV3 = R"sql(
CREATE TABLE fogbench.station_keys (
  station_id      text NOT NULL,
  key_id          text NOT NULL CHECK (key_id ~ '^[0-9a-f]{64}$'),
  public_key_pem  text NOT NULL,
  first_seen      timestamptz NOT NULL,
  revoked_at      timestamptz,
  PRIMARY KEY (station_id, key_id)
);
CREATE INDEX station_keys_key_id ON fogbench.station_keys (key_id);
)sql";

// Version 4 (issue 24, one verdict per serial): the verdicts the benches decided (a plan's limits
// or the analysis settings, the bench's table verdicts), replicated with the run that decided
// them. The fleet's verdicts (serials, history, p-charts) are read from here, never from the
// verifications, whose own `verdict` is the analysis settings' computation only.
constexpr const char* kV4 = R"sql(
CREATE TABLE fogbench.verdicts (
  bench_id      text NOT NULL,
  verdict_id    bigint NOT NULL,
  serial        text NOT NULL,
  run_id        bigint NOT NULL,
  unit_index    integer NOT NULL,
  model_id      bigint,
  verdict       text NOT NULL CHECK (verdict IN ('pass', 'marginal', 'fail', 'incomplete')),
  rule          text NOT NULL CHECK (rule IN ('plan', 'analysis')),
  plan_id       bigint,
  plan_name     text NOT NULL DEFAULT '',
  plan_sha256   text NOT NULL DEFAULT '',
  limits_json   jsonb NOT NULL,
  reasons_json  jsonb NOT NULL,
  decided_at    timestamptz NOT NULL,
  PRIMARY KEY (bench_id, verdict_id),
  FOREIGN KEY (bench_id, run_id) REFERENCES fogbench.runs ON DELETE CASCADE
);
CREATE INDEX verdicts_serial ON fogbench.verdicts (serial);
CREATE INDEX verdicts_run ON fogbench.verdicts (bench_id, run_id, unit_index);
)sql";

// Version 5 (issue 29): what a run on the rate table and a three-axis unit add to a sample (the
// table's commanded rate, deg/s; the y and z axes, deg/h; NULL where the bench recorded none), and
// each unit's gyro axes (1 or 3; a run replicated before this version reads 1).
constexpr const char* kV5 = R"sql(
ALTER TABLE fogbench.samples ADD COLUMN rate_in_dps double precision,
                             ADD COLUMN gyro_y_dph double precision,
                             ADD COLUMN gyro_z_dph double precision;
ALTER TABLE fogbench.units ADD COLUMN axes smallint NOT NULL DEFAULT 1 CHECK (axes IN (1, 3));
)sql";

// Version 6 (issue 29): the bench's schema 14. A model's axis ('x', 'y' or 'z' for a three-axis
// unit's, NULL for a one-axis unit's; its model_json says the same) and a three-axis unit's
// verdict's evidence per axis (a JSON array of {axis, verdict, model_id, limits, reasons}; NULL
// for a one-axis unit's verdict). Rows replicated before read NULL: one-axis, as they were.
constexpr const char* kV6 = R"sql(
ALTER TABLE fogbench.models ADD COLUMN axis text CHECK (axis IN ('x', 'y', 'z'));
ALTER TABLE fogbench.verdicts ADD COLUMN axes_json jsonb;
)sql";

// Version 7 (issue 29): the bench's schema 15. A three-axis unit's coil thermistors per axis
// (degC; t1 at the coil's centre, t2 at its outer wall, as t1_c and t2_c; NULL where the unit's
// thermistors are shared or the bench recorded none). Samples replicated before read NULL.
constexpr const char* kV7 = R"sql(
ALTER TABLE fogbench.samples ADD COLUMN t1_y_c double precision,
                             ADD COLUMN t2_y_c double precision,
                             ADD COLUMN t1_z_c double precision,
                             ADD COLUMN t2_z_c double precision;
)sql";

constexpr Migration kMigrations[] = {
    {1, "runs, units, samples, events, models, verifications, figures", kV1},
    {2, "samples.compensated_dph, run_identity, unit_identity, certificates", kV2},
    {3, "station_keys", kV3},
    {4, "verdicts", kV4},
    {5, "samples.rate_in_dps, gyro_y_dph, gyro_z_dph, units.axes", kV5},
    {6, "models.axis, verdicts.axes_json", kV6},
    {7, "samples.t1_y_c, t2_y_c, t1_z_c, t2_z_c", kV7},
};

constexpr int kCurrent = 7;

// The version recorded, 0 when the schema is absent.
PlantResult<int> read_version(Connection& c) {
  auto has = c.query("SELECT to_regclass('fogbench.schema_version') IS NOT NULL", {}, "read the plant's schema version");
  if (!has) return std::unexpected(has.error());
  if (has->rows.at(0).at(0).value_or("f") != "t") return 0;
  auto v = c.query("SELECT coalesce(max(version), 0) FROM fogbench.schema_version", {},
                   "read the plant's schema version");
  if (!v) return std::unexpected(v.error());
  return std::stoi(v->rows.at(0).at(0).value_or("0"));
}

PlantError too_new(int v) {
  return {PlantErrc::schema_too_new,
          "the plant's schema version " + std::to_string(v) + " is newer than this fogbench knows (" +
              std::to_string(kCurrent) + "); it was written by a newer fogbench: use that, this one will not touch it"};
}

PlantResult<int> migrate(Connection& c) {
  // One transaction per step, serialised between benches by an advisory lock: two benches
  // starting at once do not both create the tables.
  for (const Migration& m : kMigrations) {
    const std::string what = "migrate the plant's schema " + std::to_string(m.version - 1) + " -> " +
                             std::to_string(m.version) + " (" + m.what + ")";
    auto fail = [&](PlantError e) {
      (void)c.exec("ROLLBACK", what);
      if (e.code == PlantErrc::sql) e.code = PlantErrc::migration_failed;
      return std::unexpected(std::move(e));
    };
    if (auto ok = c.exec("BEGIN", what); !ok) return std::unexpected(ok.error());
    if (auto ok = c.exec("SELECT pg_advisory_xact_lock(745201414)", what); !ok) return fail(ok.error());
    if (auto ok = c.exec("CREATE SCHEMA IF NOT EXISTS fogbench; "
                         "CREATE TABLE IF NOT EXISTS fogbench.schema_version (version integer PRIMARY KEY, "
                         "what text NOT NULL, migrated_at timestamptz NOT NULL DEFAULT now())",
                         what);
        !ok)
      return fail(ok.error());
    auto now = read_version(c);
    if (!now) return fail(now.error());
    if (*now > kCurrent) return fail(too_new(*now));
    if (*now >= m.version) {
      if (auto ok = c.exec("COMMIT", what); !ok) return std::unexpected(ok.error());
      continue;
    }
    if (auto ok = c.exec(m.sql, what); !ok) return fail(ok.error());
    if (auto ok = c.query("INSERT INTO fogbench.schema_version (version, what) VALUES ($1, $2)",
                          {std::to_string(m.version), std::string(m.what)}, what);
        !ok)
      return fail(ok.error());
    if (auto ok = c.exec("COMMIT", what); !ok) return std::unexpected(ok.error());
  }
  return kCurrent;
}

}  // namespace

int Connection::current_schema_version() { return kCurrent; }

namespace {

// Whether the connection string or URI names connect_timeout itself (unparsable: no; the
// connection attempt then reports the syntax error).
bool sets_connect_timeout(const std::string& conninfo) {
  PQconninfoOption* options = PQconninfoParse(conninfo.c_str(), nullptr);
  if (!options) return false;
  bool set = false;
  for (const PQconninfoOption* o = options; o->keyword; ++o)
    if (std::string_view(o->keyword) == "connect_timeout" && o->val && *o->val) set = true;
  PQconninfoFree(options);
  return set;
}

}  // namespace

PlantResult<Connection> Connection::open(const std::string& conninfo, bool do_migrate, int connect_timeout_s) {
  auto conn = std::make_unique<detail::Conn>();
  if (connect_timeout_s > 0 && !sets_connect_timeout(conninfo)) {
    // The arrays are read in order and a later keyword wins: the conninfo (expanded as the
    // first dbname) first, then the bound. A service file only fills what is still unset.
    const std::string timeout = std::to_string(connect_timeout_s);
    const char* keywords[] = {"dbname", "connect_timeout", nullptr};
    const char* values[] = {conninfo.c_str(), timeout.c_str(), nullptr};
    conn->pg = PQconnectdbParams(keywords, values, 1);
  } else {
    conn->pg = PQconnectdb(conninfo.c_str());
  }
  if (!conn->pg || PQstatus(conn->pg) != CONNECTION_OK) {
    std::string msg = conn->pg ? PQerrorMessage(conn->pg) : "out of memory";
    while (!msg.empty() && (msg.back() == '\n' || msg.back() == ' ')) msg.pop_back();
    return std::unexpected(PlantError{PlantErrc::connect_failed, "connect to the plant store: " + msg});
  }
  // The server's notices (a connection terminated by a shutdown...) are not printed on stderr:
  // what matters comes back as the failing call's error.
  PQsetNoticeProcessor(conn->pg, [](void*, const char*) {}, nullptr);
  Connection c(std::move(conn));
  (void)c.exec("SET client_min_messages = warning; SET TIME ZONE 'UTC'", "set the session");
  auto v = read_version(c);
  if (!v) return std::unexpected(v.error());
  if (*v > kCurrent) return std::unexpected(too_new(*v));
  if (*v < kCurrent) {
    if (!do_migrate) {
      if (*v == 0)
        return std::unexpected(PlantError{PlantErrc::schema_missing,
                                          "the plant store has no fogbench schema (no bench has replicated to it yet)"});
      return std::unexpected(PlantError{PlantErrc::schema_missing,
                                        "the plant's schema version " + std::to_string(*v) + " is older than " +
                                            std::to_string(kCurrent) + ": a bench running this fogbench migrates it"});
    }
    auto m = migrate(c);
    if (!m) return std::unexpected(m.error());
    v = *m;
  }
  c.version_ = *v;
  return c;
}

}  // namespace fogbench::plant
