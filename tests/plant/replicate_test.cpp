// Replication to a real PostgreSQL started by the test (issue 14, points 1 and 4): a real
// completed run from a real SQLite store, sent twice, the server killed mid-COPY, and the
// refusals (a login refused, a newer schema, a bad lot id).
#include <catch2/catch.hpp>

#include <chrono>
#include <future>
#include <thread>

#include "bench_run.hpp"
#include "fogbench/plant/fleet.hpp"
#include "fogbench/plant/plant.hpp"
#include "fogbench/plant/verdicts.hpp"
#include "fogbench/signing/certificate.hpp"
#include "fogbench/storage/outbox.hpp"
#include "pg_server.hpp"

using namespace fogbench;
using test::PgServer;

namespace {

std::int64_t count(plant::Connection& c, const std::string& sql) {
  auto r = c.query(sql, {}, "count");
  REQUIRE(r);
  return std::stoll(r->rows.at(0).at(0).value_or("0"));
}

storage::Store open_store(const std::filesystem::path& p) {
  auto s = storage::Store::open(p);
  REQUIRE(s);
  return std::move(*s);
}

// The identity a bench's fogbenchd records with a run (issue 13): unit 0 seen powering on,
// unit 1 not (it was on before the daemon started).
storage::RunIdentity bench_identity() {
  storage::RunIdentity id;
  id.station_id = "station-7";
  id.operator_name = "Ada O'Lovelace";
  id.operator_source = "client";
  id.software_version = "0.1.0";
  id.git_hash = "58b9f8ad20ce2bfcb4bae6985d95cf60120ac562";
  id.config_sha256 = std::string(64, 'a');
  id.profile_sha256 = std::string(64, 'b');
  id.units = {{0, "FOG-0001", "2026-11-25T08:00:00Z", 120.5}, {1, "FOG-0002", std::nullopt, std::nullopt}};
  return id;
}

// One value of a one-row query, or nullopt for NULL.
std::optional<std::string> value(plant::Connection& c, const std::string& sql, const std::vector<std::optional<std::string>>& params) {
  auto r = c.query(sql, params, "value");
  REQUIRE(r);
  REQUIRE(r->rows.size() == 1);
  return r->rows.at(0).at(0);
}

}  // namespace

TEST_CASE("a completed run of a real SQLite store replicates whole, and sending it twice changes nothing") {
  PgServer pg;
  auto path = test::temp_store_path("whole");
  auto bench = open_store(path);
  const std::string quoted = "LOT-\"7\" O'Neil; DROP TABLE x --";
  const auto id = test::record_run(bench, {std::string("LOT-A"), quoted}, 1, 5, true, bench_identity());
  // A certificate of unit 1's model (its JSON as canonical bytes, which its hash is of).
  const std::string cert_json = R"({"model":{"id":2},"serial":"FOG-0002","sha256":"","text":"a tab\there"})";
  {
    auto ms = bench.list_models("FOG-0002");
    REQUIRE(ms);
    REQUIRE(ms->size() == 1);
    REQUIRE(bench.put_certificate({"FOG-0002", ms->front().id, ms->front().version, std::string(64, 'c'), cert_json}));
  }
  REQUIRE(bench.enqueue_replication(id));
  // Queued twice while waiting: one entry.
  CHECK(*bench.enqueue_replication(id) == *bench.enqueue_replication(id));
  CHECK(bench.outbox_status()->depth == 1);

  auto c = plant::Connection::open(pg.conninfo(), true);
  REQUIRE(c);
  CHECK(c->schema_version() == plant::Connection::current_schema_version());
  auto sent = plant::send_outbox(*c, bench, "bench-1", 100);
  REQUIRE(sent);
  CHECK(*sent == 1);
  auto st = bench.outbox_status();
  CHECK(st->depth == 0);
  CHECK(st->sent == 1);
  CHECK(st->last_sent_at.has_value());

  const std::int64_t n = *bench.count_samples(id);
  REQUIRE(n > 10000);
  const std::string rid = std::to_string(id);
  CHECK(count(*c, "SELECT count(*) FROM fogbench.samples WHERE bench_id = 'bench-1' AND run_id = " + rid) == n);
  // Every value as stored: the sums over the bench's samples and the plant's agree to rounding,
  // and NULLs (a signal not read) stay NULL.
  double gyro = 0, t1 = 0;
  std::int64_t no_power_on = 0, flagged = 0;
  for (int u = 0; u < 2; ++u) {
    auto rows = bench.get_samples(id, u, 0, 1000000);
    REQUIRE(rows);
    for (const auto& r : *rows) {
      gyro += r.gyro_dph;
      t1 += r.t1_c;
      no_power_on += std::isnan(r.since_power_on_s);
      flagged += r.flags != 0;
    }
  }
  auto sums = c->query("SELECT sum(gyro_dph), sum(t1_c), count(*) FILTER (WHERE since_power_on_s IS NULL), "
                       "count(*) FILTER (WHERE flags <> 0) FROM fogbench.samples WHERE run_id = $1",
                       {rid}, "sums");
  REQUIRE(sums);
  CHECK(std::stod(*sums->rows[0][0]) == Approx(gyro).epsilon(1e-12));
  CHECK(std::stod(*sums->rows[0][1]) == Approx(t1).epsilon(1e-12));
  CHECK(std::stoll(*sums->rows[0][2]) == no_power_on);
  CHECK(std::stoll(*sums->rows[0][3]) == flagged);
  CHECK(no_power_on > 0);
  // The compensated rate, NULL where the daemon computed none.
  double compensated = 0;
  std::int64_t n_compensated = 0;
  for (int u = 0; u < 2; ++u) {
    auto rows = bench.get_samples(id, u, 0, 1000000);
    REQUIRE(rows);
    for (const auto& r : *rows)
      if (!std::isnan(r.compensated_dph)) {
        compensated += r.compensated_dph;
        ++n_compensated;
      }
  }
  REQUIRE(n_compensated > 0);
  REQUIRE(n_compensated < n);
  auto comp = c->query("SELECT sum(compensated_dph), count(compensated_dph) FROM fogbench.samples WHERE run_id = $1",
                       {rid}, "compensated");
  REQUIRE(comp);
  CHECK(std::stod(*comp->rows[0][0]) == Approx(compensated).epsilon(1e-12));
  CHECK(std::stoll(*comp->rows[0][1]) == n_compensated);

  // The run's identity and its units' power-on, exactly as the bench holds them.
  auto ident = c->query("SELECT station_id, operator, operator_source, software_version, git_hash, config_sha256, "
                        "profile_sha256 FROM fogbench.run_identity WHERE bench_id = 'bench-1' AND run_id = $1",
                        {rid}, "identity");
  REQUIRE(ident);
  REQUIRE(ident->rows.size() == 1);
  const auto want = bench_identity();
  CHECK(ident->rows[0][0] == std::optional(want.station_id));
  CHECK(ident->rows[0][1] == std::optional(want.operator_name));
  CHECK(ident->rows[0][2] == std::optional<std::string>("client"));
  CHECK(ident->rows[0][3] == std::optional(want.software_version));
  CHECK(ident->rows[0][4] == std::optional(want.git_hash));
  CHECK(ident->rows[0][5] == std::optional(want.config_sha256));
  CHECK(ident->rows[0][6] == std::optional(want.profile_sha256));
  auto uid = c->query("SELECT unit_index, powered_on_at = '2026-11-25T08:00:00Z'::timestamptz, since_power_on_s "
                      "FROM fogbench.unit_identity WHERE run_id = $1 ORDER BY unit_index",
                      {rid}, "unit identity");
  REQUIRE(uid);
  REQUIRE(uid->rows.size() == 2);
  CHECK(uid->rows[0][1] == std::optional<std::string>("t"));
  CHECK(std::stod(*uid->rows[0][2]) == 120.5);
  CHECK_FALSE(uid->rows[1][1].has_value());
  CHECK_FALSE(uid->rows[1][2].has_value());

  // The certificate of unit 1's serial, its JSON byte for byte (its hash is of those bytes).
  auto certs = bench.list_certificates("FOG-0002");
  REQUIRE(certs);
  REQUIRE(certs->size() == 1);
  CHECK(count(*c, "SELECT count(*) FROM fogbench.certificates") == 1);
  CHECK(value(*c, "SELECT json FROM fogbench.certificates WHERE bench_id = 'bench-1' AND certificate_id = $1",
              {std::to_string(certs->front().id)}) == std::optional(cert_json));
  CHECK(value(*c, "SELECT serial || ' ' || model_id || ' ' || model_version || ' ' || sha256 FROM fogbench.certificates",
              {}) == std::optional("FOG-0002 " + std::to_string(certs->front().model_id) + " " +
                                   std::to_string(certs->front().model_version) + " " + std::string(64, 'c')));

  // Units with their lots exactly (the quotes are data, never SQL).
  auto units = c->query("SELECT serial, lot FROM fogbench.units WHERE run_id = $1 ORDER BY unit_index", {rid}, "units");
  REQUIRE(units);
  REQUIRE(units->rows.size() == 2);
  CHECK(units->rows[0][1] == std::optional<std::string>("LOT-A"));
  CHECK(units->rows[1][1] == std::optional<std::string>(quoted));
  // Events with their JSON detail intact (tabs, quotes, backslashes through COPY).
  auto detail = bench.get_run(id);
  REQUIRE(detail);
  CHECK(count(*c, "SELECT count(*) FROM fogbench.events WHERE run_id = " + rid) ==
        static_cast<std::int64_t>(detail->events.size()));
  auto note = c->query("SELECT detail::text FROM fogbench.events WHERE run_id = $1 AND kind = 'note'", {rid}, "note");
  REQUIRE(note);
  REQUIRE(note->rows.size() == 1);
  CHECK(nlohmann::json::parse(*note->rows[0][0])["text"] == "a tab\there, a quote ' and \" and a \\ backslash");
  // Models, verifications, and each model's coefficients as figures.
  CHECK(count(*c, "SELECT count(*) FROM fogbench.models WHERE run_id = " + rid) == 2);
  CHECK(count(*c, "SELECT count(*) FROM fogbench.verifications WHERE run_id = " + rid) == 2);
  auto models = bench.list_models("FOG-0002");
  REQUIRE(models);
  REQUIRE(models->size() == 1);
  const auto mj = nlohmann::json::parse(models->front().model_json);
  for (const auto& t : mj["terms"]) {
    auto v = c->query("SELECT value FROM fogbench.figures WHERE source = 'model' AND source_id = $1 AND name = $2",
                      {std::to_string(models->front().id), t["term"].get<std::string>()}, "figure");
    REQUIRE(v);
    REQUIRE(v->rows.size() == 1);
    CHECK(std::stod(*v->rows[0][0]) == Approx(t["coef"].get<double>()).epsilon(1e-12));
  }
  CHECK(count(*c, "SELECT count(*) FROM fogbench.figures WHERE source = 'verification' AND name = 'ratio'") == 2);

  // The fleet queries find the unit by its quoted lot.
  plant::FleetFilter f;
  f.lot = quoted;
  auto serials = plant::serials(*c, f);
  REQUIRE(serials);
  REQUIRE(serials->size() == 1);
  CHECK(serials->front().serial == "FOG-0002");
  CHECK(serials->front().last_verdict.has_value());
  auto history = plant::serial_history(*c, "FOG-0002", {});
  REQUIRE(history);
  REQUIRE(history->size() == 1);
  CHECK(history->front().lot == std::optional<std::string>(quoted));
  CHECK(history->front().figures.size() >= 5);

  // Sending again replaces: the same rows, none twice.
  REQUIRE(bench.enqueue_replication(id));
  REQUIRE(*plant::send_outbox(*c, bench, "bench-1", 100) == 1);
  CHECK(count(*c, "SELECT count(*) FROM fogbench.samples") == n);
  CHECK(count(*c, "SELECT count(*) FROM fogbench.runs") == 1);
  CHECK(count(*c, "SELECT count(*) FROM fogbench.models") == 2);
  CHECK(count(*c, "SELECT count(*) FROM fogbench.figures WHERE name = 'ratio'") == 2);
  CHECK(count(*c, "SELECT count(*) FROM fogbench.events WHERE run_id = " + rid) ==
        static_cast<std::int64_t>(detail->events.size()));
  CHECK(count(*c, "SELECT count(*) FROM fogbench.run_identity") == 1);
  CHECK(count(*c, "SELECT count(*) FROM fogbench.unit_identity") == 2);
  CHECK(count(*c, "SELECT count(*) FROM fogbench.certificates") == 1);
  CHECK(count(*c, "SELECT count(compensated_dph) FROM fogbench.samples") == n_compensated);
  // Another bench's run 1 is another run; the stats count what was written, identity rows and
  // certificates included (the certificate is new under this bench id).
  auto first = plant::replicate_run(*c, bench, "bench-2", id);
  REQUIRE(first);
  CHECK(first->units == 2);
  CHECK(first->samples == n);
  CHECK(first->events == static_cast<std::int64_t>(detail->events.size()));
  CHECK(first->models == 2);
  CHECK(first->verifications == 2);
  CHECK(first->identity_rows == 3);  // the run's and its two units'
  CHECK(first->certificates == 1);
  CHECK(first->certificates_held == 0);
  CHECK(first->figures == count(*c, "SELECT count(*) FROM fogbench.figures WHERE bench_id = 'bench-2'"));
  CHECK(count(*c, "SELECT count(*) FROM fogbench.samples") == 2 * n);
  CHECK(count(*c, "SELECT count(DISTINCT bench_id) FROM fogbench.runs") == 2);
  CHECK(count(*c, "SELECT count(*) FROM fogbench.run_identity") == 2);
  CHECK(count(*c, "SELECT count(*) FROM fogbench.certificates") == 2);
  // Sent again: the identity rewritten, the certificate already held and left as it is.
  auto again = plant::replicate_run(*c, bench, "bench-2", id);
  REQUIRE(again);
  CHECK(again->samples == n);
  CHECK(again->identity_rows == 3);
  CHECK(again->certificates == 0);
  CHECK(again->certificates_held == 1);
  CHECK(count(*c, "SELECT count(*) FROM fogbench.certificates") == 2);
  std::filesystem::remove(path);
}

TEST_CASE("the server killed mid-COPY commits nothing, the outbox keeps the run, and it catches up in order") {
  PgServer pg;
  auto path = test::temp_store_path("kill");
  auto bench = open_store(path);
  // A large run (40 copies of exp1 per unit: about 430,000 samples) and a small one after it.
  const auto big = test::record_run(bench, {std::string("L1"), std::string("L1")}, 40, 7, false);
  const auto small = test::record_run(bench, {std::string("L2"), std::nullopt}, 1, 8, false);
  REQUIRE(bench.enqueue_replication(big));
  REQUIRE(bench.enqueue_replication(small));
  const std::int64_t n_big = *bench.count_samples(big), n_small = *bench.count_samples(small);

  {
    auto c = plant::Connection::open(pg.conninfo(), true);
    REQUIRE(c);
    auto sending = std::async(std::launch::async, [&] { return plant::send_outbox(*c, bench, "b1", 100); });
    // The server is killed while the big run's samples are being copied.
    bool copying = false;
    for (int i = 0; i < 3000 && !copying; ++i) {
      copying = pg.psql("SELECT count(*) FROM pg_stat_activity WHERE query LIKE 'COPY fogbench.samples%' AND "
                        "state IN ('active', 'idle in transaction')") != "0";
      if (!copying) std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    REQUIRE(copying);
    pg.kill_immediate();
    auto r = sending.get();
    REQUIRE_FALSE(r);
    CHECK(r.error().code == plant::PlantErrc::connection_lost);
    CHECK_THAT(r.error().message, Catch::Contains("run " + std::to_string(big)));
  }
  // Nothing lost on the bench: both still queued, the first with its error.
  auto st = bench.outbox_status();
  REQUIRE(st);
  CHECK(st->depth == 2);
  CHECK(st->attempts == 1);
  CHECK_FALSE(st->last_error.empty());

  pg.start();
  auto c = plant::Connection::open(pg.conninfo(), true);
  REQUIRE(c);
  // Nothing half-written in the plant.
  CHECK(count(*c, "SELECT count(*) FROM fogbench.samples") == 0);
  CHECK(count(*c, "SELECT count(*) FROM fogbench.runs") == 0);
  // Catch-up: both, in the order queued, every sample once.
  auto sent = plant::send_outbox(*c, bench, "b1", 100);
  REQUIRE(sent);
  CHECK(*sent == 2);
  CHECK(bench.outbox_status()->depth == 0);
  CHECK(count(*c, "SELECT count(*) FROM fogbench.samples WHERE run_id = " + std::to_string(big)) == n_big);
  CHECK(count(*c, "SELECT count(*) FROM fogbench.samples WHERE run_id = " + std::to_string(small)) == n_small);
  CHECK(count(*c, "SELECT count(*) FROM (SELECT 1 FROM fogbench.samples GROUP BY bench_id, run_id, unit_index, t_s "
                  "HAVING count(*) > 1) d") == 0);
  CHECK(count(*c, "SELECT count(*) FROM fogbench.runs a JOIN fogbench.runs b ON a.run_id = " + std::to_string(big) +
                      " AND b.run_id = " + std::to_string(small) + " WHERE a.replicated_at < b.replicated_at") == 1);
  // Runs recorded without an identity (as before issue 13) and with no certificates: none sent.
  CHECK(count(*c, "SELECT count(*) FROM fogbench.run_identity") == 0);
  CHECK(count(*c, "SELECT count(*) FROM fogbench.unit_identity") == 0);
  CHECK(count(*c, "SELECT count(*) FROM fogbench.certificates") == 0);
  std::filesystem::remove(path);
}

TEST_CASE("a refused login, a newer schema and bad ids are clear errors and write nothing") {
  PgServer pg;
  SECTION("a login refused") {
    auto c = plant::Connection::open(pg.tcp_conninfo("wrong"), true);
    REQUIRE_FALSE(c);
    CHECK(c.error().code == plant::PlantErrc::connect_failed);
    CHECK_THAT(c.error().message, Catch::Contains("password authentication failed for user \"postgres\""));
  }
  SECTION("a reader of a database no bench has written") {
    auto c = plant::Connection::open(pg.conninfo(), false);
    REQUIRE_FALSE(c);
    CHECK(c.error().code == plant::PlantErrc::schema_missing);
  }
  SECTION("a schema newer than this fogbench") {
    REQUIRE(plant::Connection::open(pg.conninfo(), true));
    pg.psql("INSERT INTO fogbench.schema_version (version, what) VALUES (99, 'from the future')");
    for (bool migrate : {true, false}) {
      auto c = plant::Connection::open(pg.conninfo(), migrate);
      REQUIRE_FALSE(c);
      CHECK(c.error().code == plant::PlantErrc::schema_too_new);
      CHECK_THAT(c.error().message, Catch::Contains("schema version 99 is newer"));
    }
    CHECK(pg.psql("SELECT string_agg(version::text, ',' ORDER BY version) FROM fogbench.schema_version") == "1,2,3,4,5,6,7,99");
  }
  SECTION("a lot id with a control character, an empty bench id") {
    auto path = test::temp_store_path("badlot");
    auto bench = open_store(path);
    const auto id = test::record_run(bench, {std::string("ok"), std::string("bad\nlot")}, 1, 3, false);
    REQUIRE(bench.enqueue_replication(id));
    auto c = plant::Connection::open(pg.conninfo(), true);
    REQUIRE(c);
    auto r = plant::send_outbox(*c, bench, "b1", 10);
    REQUIRE_FALSE(r);
    CHECK(r.error().code == plant::PlantErrc::invalid_argument);
    CHECK_THAT(r.error().message, Catch::Contains("lot id of unit 1: a control character at position 4"));
    auto st = bench.outbox_status();
    CHECK(st->depth == 1);
    CHECK_THAT(st->last_error, Catch::Contains("lot id of unit 1"));
    auto e = plant::replicate_run(*c, bench, "", id);
    REQUIRE_FALSE(e);
    CHECK_THAT(e.error().message, Catch::Contains("bench id: empty"));
    CHECK(count(*c, "SELECT count(*) FROM fogbench.runs") == 0);
    CHECK(count(*c, "SELECT count(*) FROM fogbench.samples") == 0);
    std::filesystem::remove(path);
  }
}

TEST_CASE("a plant at schema 1 migrates to 6 on a bench's connection, keeping what it held") {
  PgServer pg;
  auto path = test::temp_store_path("migrate");
  auto bench = open_store(path);
  const auto old_run = test::record_run(bench, {std::string("L1"), std::nullopt}, 1, 3, false);
  {
    // A plant as a fogbench of schema 1 left it: a run replicated, then version 2's additions
    // taken away again (exactly what migration 2 adds).
    auto c = plant::Connection::open(pg.conninfo(), true);
    REQUIRE(c);
    auto st = plant::replicate_run(*c, bench, "b1", old_run);
    REQUIRE(st);
    // A run recorded without an identity, of serials without certificates: none counted.
    CHECK(st->identity_rows == 0);
    CHECK(st->certificates == 0);
    CHECK(st->certificates_held == 0);
    REQUIRE(c->exec("ALTER TABLE fogbench.samples DROP COLUMN compensated_dph, DROP COLUMN rate_in_dps, "
                    "DROP COLUMN gyro_y_dph, DROP COLUMN gyro_z_dph, DROP COLUMN t1_y_c, DROP COLUMN t2_y_c, "
                    "DROP COLUMN t1_z_c, DROP COLUMN t2_z_c; ALTER TABLE fogbench.units DROP COLUMN axes; "
                    "ALTER TABLE fogbench.models DROP COLUMN axis; "
                    "DROP TABLE fogbench.run_identity, fogbench.unit_identity, fogbench.certificates, "
                    "fogbench.station_keys, fogbench.verdicts; DELETE FROM fogbench.schema_version WHERE version >= 2",
                    "back to schema 1"));
  }
  CHECK(pg.psql("SELECT string_agg(version::text, ',' ORDER BY version) FROM fogbench.schema_version") == "1");
  CHECK(pg.psql("SELECT to_regclass('fogbench.run_identity') IS NULL") == "t");
  // A reader does not migrate: it names the versions.
  auto reader = plant::Connection::open(pg.conninfo(), false);
  REQUIRE_FALSE(reader);
  CHECK(reader.error().code == plant::PlantErrc::schema_missing);
  CHECK_THAT(reader.error().message, Catch::Contains("schema version 1 is older than 7"));

  // A bench migrates: version 2 recorded, the run held before kept (its samples' compensated
  // rate NULL), and a run with identity and compensated rates then replicates in full.
  auto c = plant::Connection::open(pg.conninfo(), true);
  REQUIRE(c);
  CHECK(c->schema_version() == 7);
  CHECK(pg.psql("SELECT string_agg(version::text, ',' ORDER BY version) FROM fogbench.schema_version") == "1,2,3,4,5,6,7");
  const std::string old_rid = std::to_string(old_run);
  CHECK(count(*c, "SELECT count(*) FROM fogbench.samples WHERE run_id = " + old_rid) == *bench.count_samples(old_run));
  CHECK(count(*c, "SELECT count(compensated_dph) FROM fogbench.samples") == 0);
  // Version 5's columns: the run held before reads no table rate, no y or z, and one axis.
  CHECK(count(*c, "SELECT count(rate_in_dps) + count(gyro_y_dph) + count(gyro_z_dph) FROM fogbench.samples") == 0);
  CHECK(pg.psql("SELECT string_agg(DISTINCT axes::text, ',') FROM fogbench.units WHERE run_id = " + old_rid) == "1");
  const auto run = test::record_run(bench, {std::string("L2"), std::nullopt}, 1, 4, false, bench_identity());
  auto st = plant::replicate_run(*c, bench, "b1", run);
  REQUIRE(st);
  CHECK(st->identity_rows == 3);
  CHECK(count(*c, "SELECT count(*) FROM fogbench.run_identity WHERE run_id = " + std::to_string(run)) == 1);
  CHECK(count(*c, "SELECT count(*) FROM fogbench.unit_identity WHERE run_id = " + std::to_string(run)) == 2);
  CHECK(count(*c, "SELECT count(compensated_dph) FROM fogbench.samples WHERE run_id = " + std::to_string(run)) > 0);
  CHECK(st->verdicts == 0);

  // The verdict a run decided (issue 24) travels with it, and the fleet's verdicts read it.
  storage::NewVerdict v;
  v.serial = bench.get_run(run)->run.units[1].serial;
  v.run_id = run;
  v.unit_index = 1;
  v.verdict = "marginal";
  v.rule = "analysis";
  v.limits_json = R"([{"limit":"value < limit","measurement":"compensated std / raw std","value":0.1,"bound":0.2,"met":true}])";
  REQUIRE(bench.put_verdict(v));
  auto again = plant::replicate_run(*c, bench, "b1", run);
  REQUIRE(again);
  CHECK(again->verdicts == 1);
  CHECK(pg.psql("SELECT verdict || ' ' || rule || ' ' || unit_index || ' ' || (limits_json->0->>'bound') FROM fogbench.verdicts "
                "WHERE run_id = " + std::to_string(run)) == "marginal analysis 1 0.2");
  // A one-axis unit's verdict has no per-axis evidence (version 6's column NULL).
  CHECK(count(*c, "SELECT count(axes_json) FROM fogbench.verdicts WHERE run_id = " + std::to_string(run)) == 0);
  // A three-axis unit's verdict travels with each axis' evidence (the bench's schema 14), so the
  // plant holds which axis failed, not only that the unit did.
  storage::NewVerdict three = v;
  three.unit_index = 0;
  three.serial = bench.get_run(run)->run.units[0].serial;
  three.verdict = "fail";
  three.axes_json = R"([{"axis":"x","verdict":"pass","model_id":null,"limits":[],"reasons":[]},)"
                    R"({"axis":"y","verdict":"fail","model_id":null,"limits":[],"reasons":["noise factor 11.9"]},)"
                    R"({"axis":"z","verdict":"pass","model_id":null,"limits":[],"reasons":[]}])";
  REQUIRE(bench.put_verdict(three));
  auto third = plant::replicate_run(*c, bench, "b1", run);
  REQUIRE(third);
  CHECK(third->verdicts == 2);
  CHECK(pg.psql("SELECT (axes_json->1->>'axis') || ' ' || (axes_json->1->>'verdict') || ' ' || (axes_json->1->'reasons'->>0) "
                "FROM fogbench.verdicts WHERE run_id = " + std::to_string(run) + " AND unit_index = 0") == "y fail noise factor 11.9");
  plant::FleetFilter f;
  f.serial = v.serial;
  auto values = plant::verdict_values(*c, f);
  REQUIRE(values);
  REQUIRE(values->size() == 1);
  CHECK(values->front().verdict == "marginal");

  // The run sent at schema 1 had its verdict decided too: the plant had no table for it then.
  // The link's reconciliation sends it, once; a verdict of a run the plant does not hold yet
  // waits for its run, and one the plant holds is left as it is.
  storage::NewVerdict old_v = v;
  old_v.run_id = old_run;
  old_v.unit_index = 0;
  old_v.serial = bench.get_run(old_run)->run.units[0].serial;
  old_v.verdict = "pass";
  REQUIRE(bench.put_verdict(old_v));
  const auto unsent = test::record_run(bench, {std::nullopt, std::nullopt}, 1, 6, false);
  storage::NewVerdict unsent_v = old_v;
  unsent_v.run_id = unsent;
  REQUIRE(bench.put_verdict(unsent_v));
  auto sent = plant::send_missing_verdicts(*c, bench, "b1");
  REQUIRE(sent);
  CHECK(*sent == 1);
  CHECK(pg.psql("SELECT verdict || ' ' || unit_index FROM fogbench.verdicts WHERE run_id = " + old_rid) == "pass 0");
  CHECK(count(*c, "SELECT count(*) FROM fogbench.verdicts WHERE run_id = " + std::to_string(unsent)) == 0);
  // The run's two (unit 1's marginal, unit 0's three-axis fail) and the old run's one.
  CHECK(count(*c, "SELECT count(*) FROM fogbench.verdicts") == 3);
  sent = plant::send_missing_verdicts(*c, bench, "b1");
  REQUIRE(sent);
  CHECK(*sent == 0);
  std::filesystem::remove(path);
}

TEST_CASE("the public key that signed a run's certificates reaches station_keys once, its earliest date kept, a mismatched key refused") {
  PgServer pg;
  auto path = test::temp_store_path("keys");
  auto bench = open_store(path);
  const auto id = test::record_run(bench, {std::string("L1"), std::string("L1")}, 1, 3, true, bench_identity());
  auto ms = bench.list_models("FOG-0002");
  REQUIRE(ms);
  REQUIRE(ms->size() == 1);
  auto key = signing::SigningKey::generate();
  auto other = signing::SigningKey::generate();
  REQUIRE(key);
  REQUIRE(other);
  auto put = [&](const signing::SigningKey& k, const std::string& issued_at, bool swap_pem) {
    nlohmann::json c = {{"format", "fogbench.certificate"}, {"serial", "FOG-0002"}, {"station_id", "line-2"},
                        {"model", {{"id", ms->front().id}, {"version", ms->front().version}}}, {"issued_at", issued_at}};
    REQUIRE(signing::sign_certificate(c, k, "line-2"));
    // A certificate whose embedded public key is not the one its key id names.
    if (swap_pem) c["signed_by"]["public_key_pem"] = key->public_key().pem();
    REQUIRE(bench.put_certificate({"FOG-0002", ms->front().id, ms->front().version, c["sha256"].get<std::string>(), c.dump()}));
  };
  put(*key, "2026-11-27T09:00:00Z", false);
  put(*key, "2026-11-27T10:00:00Z", false);
  put(*other, "2026-11-27T11:00:00Z", true);
  // An unsigned certificate of before issue 24: no key.
  REQUIRE(bench.put_certificate({"FOG-0002", ms->front().id, ms->front().version, std::string(64, 'd'), R"({"serial":"FOG-0002"})"}));

  auto c = plant::Connection::open(pg.conninfo(), true);
  REQUIRE(c);
  auto st = plant::replicate_run(*c, bench, "b1", id);
  REQUIRE(st);
  CHECK(st->certificates == 4);
  CHECK(st->station_keys == 1);
  CHECK(st->station_keys_refused == 1);
  CHECK(count(*c, "SELECT count(*) FROM fogbench.station_keys") == 1);
  CHECK(value(*c, "SELECT station_id || ' ' || (revoked_at IS NULL) FROM fogbench.station_keys WHERE key_id = $1", {key->key_id()}) ==
        std::optional<std::string>("line-2 true"));
  CHECK(value(*c, "SELECT public_key_pem FROM fogbench.station_keys WHERE key_id = $1", {key->key_id()}) ==
        std::optional(key->public_key().pem()));
  // Sent again (or by another bench of the same station): held once, none new.
  auto again = plant::replicate_run(*c, bench, "b2", id);
  REQUIRE(again);
  CHECK(again->station_keys == 0);
  CHECK(count(*c, "SELECT count(*) FROM fogbench.station_keys") == 1);
  // The plant revokes a key by setting revoked_at (docs/plant.md "Station keys").
  REQUIRE(c->exec("UPDATE fogbench.station_keys SET revoked_at = '2026-11-28T00:00:00Z'", "revoke"));
  CHECK(count(*c, "SELECT count(*) FROM fogbench.station_keys WHERE revoked_at IS NOT NULL") == 1);
  std::filesystem::remove(path);
}
