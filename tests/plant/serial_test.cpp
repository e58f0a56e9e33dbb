// `fogctl fleet serial SERIAL` (cli/fleet.cpp) over runs replicated from real SQLite stores into a
// real PostgreSQL: each run's identity (station, operator, software, config and profile hashes),
// lot and bench, and the serial's certificates (hash, issued, verdict); a run recorded without an
// identity shows none; --json carries all of it.
#include <catch2/catch.hpp>

#include <sstream>

#include <nlohmann/json.hpp>

#include "bench_run.hpp"
#include "fleet.hpp"
#include "fogbench/plant/plant.hpp"
#include "pg_server.hpp"

using namespace fogbench;

TEST_CASE("fogctl fleet serial: each run's identity, lot and bench, and the serial's certificates with hash and verdict") {
  test::PgServer pg;
  auto plant = plant::Connection::open(pg.conninfo(), true);
  REQUIRE(plant);

  // Bench A records a run of FOG-0001 and FOG-0002 with its identity, and certifies FOG-0002.
  const auto path_a = test::temp_store_path("serial-a");
  auto a = storage::Store::open(path_a);
  REQUIRE(a);
  storage::RunIdentity id;
  id.station_id = "station-7";
  id.operator_name = "Ada O'Lovelace";
  id.operator_source = "client";
  id.software_version = "0.3.1";
  id.git_hash = "58b9f8ad20ce2bfcb4bae6985d95cf60120ac562";
  id.config_sha256 = "c0ffee" + std::string(58, '1');
  id.profile_sha256 = "beef00" + std::string(58, '2');
  id.units = {{0, "FOG-0001", "2026-11-25T08:00:00Z", 120.5}, {1, "FOG-0002", std::nullopt, std::nullopt}};
  const auto run_a = test::record_run(*a, {std::string("LOT-A"), std::string("LOT-B")}, 1, 5, true, id);
  auto models = a->list_models("FOG-0002");
  REQUIRE(models);
  REQUIRE(models->size() == 1);
  const std::string sha(64, 'd');
  const std::string cert_json = R"({"serial":"FOG-0002","sha256":")" + sha + R"(","verdict":"marginal"})";
  REQUIRE(a->put_certificate({"FOG-0002", models->front().id, models->front().version, sha, cert_json}));
  REQUIRE(plant::replicate_run(*plant, *a, "bench-A", run_a));

  // Bench B records a later run of the same serials without an identity (a bench before issue 13).
  const auto path_b = test::temp_store_path("serial-b");
  auto b = storage::Store::open(path_b);
  REQUIRE(b);
  const auto run_b = test::record_run(*b, {std::string("LOT-A"), std::string("LOT-B")}, 1, 6, true);
  REQUIRE(plant::replicate_run(*plant, *b, "bench-B", run_b));

  cli::FleetOptions o;
  o.db = pg.conninfo();
  o.serial = "FOG-0002";
  o.json = true;
  std::ostringstream out, err;
  REQUIRE(cli::run_fleet("serial", o, out, err) == 0);
  const auto j = nlohmann::json::parse(out.str());
  REQUIRE(j["runs"].size() == 2);
  const auto* ra = &j["runs"][0];
  const auto* rb = &j["runs"][1];
  if ((*ra)["bench"] != "bench-A") std::swap(ra, rb);
  CHECK((*ra)["bench"] == "bench-A");
  CHECK((*ra)["run_id"] == run_a);
  CHECK((*ra)["unit"] == 1);
  CHECK((*ra)["lot"] == "LOT-B");
  const auto& ij = (*ra)["identity"];
  CHECK(ij["station_id"] == "station-7");
  CHECK(ij["operator"] == "Ada O'Lovelace");
  CHECK(ij["operator_source"] == "client");
  CHECK(ij["software_version"] == "0.3.1");
  CHECK(ij["git_hash"] == id.git_hash);
  CHECK(ij["config_sha256"] == id.config_sha256);
  CHECK(ij["profile_sha256"] == id.profile_sha256);
  CHECK((*ra)["powered_on_at"].is_null());  // unit 1 was not seen powering on
  CHECK((*rb)["bench"] == "bench-B");
  CHECK((*rb)["identity"].is_null());
  REQUIRE(j["certificates"].size() == 1);
  const auto& cj = j["certificates"][0];
  CHECK(cj["bench"] == "bench-A");
  CHECK(cj["sha256"] == sha);
  CHECK(cj["verdict"] == "marginal");
  CHECK(cj["model_id"] == models->front().id);
  CHECK(cj["run_id"] == run_a);
  CHECK(cj["issued_at"].get<std::string>().size() == 20);  // YYYY-MM-DDTHH:MM:SSZ

  // Unit 0 of bench A's run: seen powering on.
  o.serial = "FOG-0001";
  std::ostringstream out0;
  REQUIRE(cli::run_fleet("serial", o, out0, err) == 0);
  const auto j0 = nlohmann::json::parse(out0.str());
  bool seen = false;
  for (const auto& r : j0["runs"])
    if (r["bench"] == "bench-A") {
      CHECK(r["powered_on_at"] == "2026-11-25T08:00:00Z");
      CHECK(r["since_power_on_s"].get<double>() == Approx(120.5));
      seen = true;
    }
  CHECK(seen);
  CHECK(j0["certificates"].empty());

  // The table: the identity's fields, the hashes shortened, the certificate with its verdict.
  o.serial = "FOG-0002";
  o.json = false;
  std::ostringstream text;
  REQUIRE(cli::run_fleet("serial", o, text, err) == 0);
  CHECK_THAT(text.str(), Catch::Contains("history of FOG-0002 (2 runs)"));
  CHECK_THAT(text.str(), Catch::Contains("station-7"));
  CHECK_THAT(text.str(), Catch::Contains("Ada O'Lovelace"));
  CHECK_THAT(text.str(), Catch::Contains("0.3.1 58b9f8ad20ce"));
  CHECK_THAT(text.str(), Catch::Contains("c0ffee111111"));
  CHECK_THAT(text.str(), Catch::Contains("beef00222222"));
  CHECK_THAT(text.str(), Catch::Contains("certificates"));
  CHECK_THAT(text.str(), Catch::Contains(sha));
  CHECK_THAT(text.str(), Catch::Contains("marginal"));
  // --bench filters the runs and the certificates alike; an unknown serial is a named error.
  o.filter.bench = "bench-B";
  std::ostringstream onlyb;
  REQUIRE(cli::run_fleet("serial", o, onlyb, err) == 0);
  CHECK_THAT(onlyb.str(), Catch::Contains("(1 run)"));
  CHECK_THAT(onlyb.str(), Catch::Contains("no certificates of FOG-0002"));
  o.filter.bench.reset();
  o.serial = "FOG-9999";
  std::ostringstream o9, e9;
  CHECK(cli::run_fleet("serial", o, o9, e9) == cli::kExitError);
  CHECK_THAT(e9.str(), Catch::Contains("no runs of serial 'FOG-9999'"));
  std::filesystem::remove(path_a);
  std::filesystem::remove(path_b);
}
