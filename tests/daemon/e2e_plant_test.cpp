// The plant store end to end (issue 14): the built fogbenchd, configured with a `plant` section,
// records runs on the built fogbench-sim (paced clock, the short profile at x200) and replicates
// them to a real PostgreSQL started by the test (tests/plant/pg_server.hpp): the samples, the
// run's identity, the models, the verification's verdict and the certificate reach the plant,
// and `status`'s outbox depth goes back to 0. Exits 77 (SKIPPED) where the server's binaries
// are missing.
#include "live_bench.hpp"

#include "../plant/pg_server.hpp"
#include "fogbench/storage/identity.hpp"
#include "fogbench/storage/models.hpp"
#include "fogbench/storage/store.hpp"

using namespace fogbench;
using namespace fogbench::daemon::test;
using namespace fogbench::daemon::test::live;
using nlohmann::json;
using namespace std::chrono_literals;

namespace {

// Runs `profile` on `units` with lots, waits until it completes (the end-of-run analysis
// stored); the run's id.
std::int64_t record(LiveBench& bench, LineClient& c, const std::vector<std::string>& units, const json& lots,
                    const std::string& purpose) {
  auto r = c.call({{"cmd", "run.start"}, {"profile", "short"}, {"units", units}, {"purpose", purpose}, {"lots", lots}});
  INFO(r.dump());
  REQUIRE(r.contains("result"));
  const auto id = r["result"]["run_id"].get<std::int64_t>();
  json done = bench.wait_state(c, id, {"completed", "aborted", "failed", "interrupted"}, 600s);
  INFO(done.dump());
  REQUIRE(done.contains("result"));
  REQUIRE(done["result"]["run"]["state"] == "completed");
  return id;
}

}  // namespace

TEST_CASE("e2e plant: fogbenchd replicates a run of the mock bench to a real PostgreSQL, and the outbox empties") {
  fogbench::test::PgServer pg;  // first: exits 77 (SKIPPED) without the server's binaries
  require_sim();
  LiveBench bench(200.0,
                  {{"station", {{"id", "line-9"}}},
                   {"plant", {{"conninfo", pg.conninfo()}, {"bench_id", "e2e-bench"}, {"poll_s", 0.1},
                              {"retry_max_s", 1}}}},
                  true);
  INFO("test dir " << bench.dir);
  LineClient c(bench.socket());
  REQUIRE(c.ok());
  json s0 = c.call({{"cmd", "status"}});
  REQUIRE(s0["result"].contains("plant"));
  CHECK(s0["result"]["plant"]["bench_id"] == "e2e-bench");
  CHECK(s0["result"]["plant"]["outbox_depth"] == 0);

  // A fit of both units, then a verification of the first (its verdict and certificate).
  const auto fit = record(bench, c, {"SIM-0001", "SIM-0002"}, {{"SIM-0001", "LOT-A"}, {"SIM-0002", "LOT-B"}}, "fit");
  const auto verify = record(bench, c, {"SIM-0001"}, {{"SIM-0001", "LOT-A"}}, "verify");

  json s = bench.wait_status(
      c,
      [](const json& r) {
        return r.contains("plant") && r["plant"].value("outbox_depth", -1) == 0 && r["plant"].value("sent", 0) >= 2;
      },
      300s);
  INFO(s.dump());
  REQUIRE(s["result"]["plant"]["outbox_depth"] == 0);
  CHECK(s["result"]["plant"]["sent"] == 2);
  CHECK(s["result"]["plant"]["last_error"].is_null());

  // What the bench holds, read from its own store (WAL: a reader beside the daemon).
  storage::OpenOptions so;
  so.create = false;
  auto store = storage::Store::open(bench.dir / "fogbench.db", so);
  REQUIRE(store);
  const std::int64_t n_fit = *store->count_samples(fit), n_verify = *store->count_samples(verify);
  REQUIRE(n_fit > 100);
  const std::string where = " WHERE bench_id = 'e2e-bench' AND run_id = ";
  const std::string f = std::to_string(fit), v = std::to_string(verify);
  // Every sample, once.
  CHECK(pg.psql("SELECT count(*) FROM fogbench.samples" + where + f) == std::to_string(n_fit));
  CHECK(pg.psql("SELECT count(*) FROM fogbench.samples" + where + v) == std::to_string(n_verify));
  CHECK(pg.psql("SELECT count(DISTINCT (unit_index, t_s)) FROM fogbench.samples" + where + f) == std::to_string(n_fit));
  CHECK(pg.psql("SELECT count(*) FROM fogbench.samples WHERE gyro_dph IS NOT NULL AND run_id = " + f) != "0");
  // The runs as completed, their units with serials and lots.
  CHECK(pg.psql("SELECT string_agg(run_id || ' ' || purpose || ' ' || state, ',' ORDER BY run_id) FROM fogbench.runs") ==
        f + " fit completed," + v + " verify completed");
  CHECK(pg.psql("SELECT string_agg(serial || '=' || lot, ',' ORDER BY unit_index) FROM fogbench.units" + where + f) ==
        "SIM-0001=LOT-A,SIM-0002=LOT-B");
  // The identity: the station's id from the configuration, one power-on row per unit.
  CHECK(pg.psql("SELECT station_id FROM fogbench.run_identity" + where + f) == "line-9");
  CHECK(pg.psql("SELECT count(*) FROM fogbench.unit_identity" + where + f) == "2");
  // The models fitted on the fit run (one per unit) with their coefficients as figures.
  auto models = store->list_models("SIM-0001");
  REQUIRE(models);
  REQUIRE_FALSE(models->empty());
  CHECK(pg.psql("SELECT count(*) FROM fogbench.models" + where + f) == "2");
  CHECK(pg.psql("SELECT count(*) FROM fogbench.figures WHERE source = 'model' AND name = 'mu0' AND run_id = " + f) ==
        "2");
  // The verification's verdict as the bench stored it, and the certificate it issued.
  auto vs = store->list_verifications(verify);
  REQUIRE(vs);
  REQUIRE(vs->size() == 1);
  const auto verdict = json::parse(vs->front().result_json).value("verdict", std::string());
  REQUIRE_FALSE(verdict.empty());
  CHECK(pg.psql("SELECT verdict FROM fogbench.verifications" + where + v) == verdict);
  auto certs = store->list_certificates("SIM-0001");
  REQUIRE(certs);
  REQUIRE(certs->size() == 1);
  CHECK(pg.psql("SELECT count(*) FROM fogbench.certificates WHERE bench_id = 'e2e-bench' AND serial = 'SIM-0001'") ==
        "1");
  CHECK(pg.psql("SELECT sha256 FROM fogbench.certificates WHERE certificate_id = " + std::to_string(certs->front().id)) ==
        certs->front().sha256);
  // The daemon's log names what each replication wrote, identity rows and certificates included.
  std::ifstream log(bench.dir / "fogbenchd.log");
  std::stringstream ss;
  ss << log.rdbuf();
  CHECK(ss.str().find("plant: run " + f + " replicated as bench 'e2e-bench' (" + std::to_string(n_fit) +
                      " samples") != std::string::npos);
  CHECK(ss.str().find("3 identity rows") != std::string::npos);
  // The station's public key, carried by the signed certificate, is in the plant's keyring.
  const json cert = json::parse(certs->front().json);
  const std::string key_id = cert["signed_by"]["key_id"];
  CHECK(pg.psql("SELECT count(*) FROM fogbench.station_keys WHERE key_id = '" + key_id + "' AND revoked_at IS NULL") == "1");
  CHECK(ss.str().find("1 station keys new") != std::string::npos);
}
