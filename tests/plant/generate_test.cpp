// The fleet generator (plant/generate.hpp) into a real PostgreSQL: every run's samples by default,
// the first N with sample_runs, committed in batches of runs (seen from a second connection
// while it generates), progress reported per run, and a re-generation that replaces.
#include <catch2/catch.hpp>

#include <string>
#include <vector>

#include "fogbench/plant/generate.hpp"
#include "pg_server.hpp"

using namespace fogbench;

TEST_CASE("plant generate: every run's samples by default, committed in batches with progress, or the first N runs") {
  test::PgServer pg;
  auto c = plant::Connection::open(pg.conninfo(), true);
  REQUIRE(c);
  plant::GenerateOptions o;
  o.runs = 12;
  o.lots = 3;
  o.shifted_lot = 1;
  o.benches = 3;
  o.outliers = 1;
  o.samples_per_unit = 50;
  o.samples_commit_runs = 5;
  REQUIRE_FALSE(o.sample_runs.has_value());  // the default: every run
  struct Seen {
    std::int64_t done, total, rows;
    std::string committed;
  };
  std::vector<Seen> seen;
  o.progress = [&](std::int64_t done, std::int64_t total, std::int64_t rows) {
    // What another client sees: only the batches committed.
    seen.push_back({done, total, rows, pg.psql("SELECT count(*) FROM fogbench.samples")});
  };
  auto g = plant::generate_fleet(*c, o);
  REQUIRE(g);
  CHECK(g->runs == 12);
  CHECK(g->samples == 12 * 2 * 50);
  REQUIRE(seen.size() == 12);
  for (std::size_t i = 0; i < seen.size(); ++i) {
    INFO("progress call " << i);
    CHECK(seen[i].done == static_cast<std::int64_t>(i + 1));
    CHECK(seen[i].total == 12);
    CHECK(seen[i].rows == static_cast<std::int64_t>(i + 1) * 100);
    // Committed every 5 runs (and at the end): 0 after runs 1-4, 500 after 5-9, 1000 after 10, 11, all at 12.
    const std::int64_t committed = seen[i].done == 12 ? 1200 : (seen[i].done / 5) * 5 * 100;
    CHECK(seen[i].committed == std::to_string(committed));
  }
  // Every unit of every run holds its 50 seconds, t_s 0..49, none twice.
  CHECK(pg.psql("SELECT count(*) FROM (SELECT bench_id, run_id, unit_index FROM fogbench.samples GROUP BY 1, 2, 3 "
                "HAVING count(*) = 50 AND min(t_s) = 0 AND max(t_s) = 49) x") == "24");
  CHECK(pg.psql("SELECT count(*) FROM fogbench.units u WHERE NOT EXISTS (SELECT 1 FROM fogbench.samples s WHERE "
                "s.bench_id = u.bench_id AND s.run_id = u.run_id AND s.unit_index = u.unit_index)") == "0");

  // The first N runs only (the quick form), replacing what was there.
  o.sample_runs = 4;
  o.progress = nullptr;
  g = plant::generate_fleet(*c, o);
  REQUIRE(g);
  CHECK(g->samples == 4 * 2 * 50);
  CHECK(pg.psql("SELECT count(*) FROM fogbench.samples") == "400");
  CHECK(pg.psql("SELECT count(*) FROM fogbench.runs") == "12");
  // The first 4 runs are runs 1 and 2 of bench 1, 1 of benches 2 and 3 (runs go to benches in turn).
  CHECK(pg.psql("SELECT string_agg(DISTINCT bench_id || ':' || run_id, ',' ORDER BY bench_id || ':' || run_id) "
                "FROM fogbench.samples") == "gen-bench-1:1,gen-bench-1:2,gen-bench-2:1,gen-bench-3:1");
  o.sample_runs = 0;
  g = plant::generate_fleet(*c, o);
  REQUIRE(g);
  CHECK(g->samples == 0);
  CHECK(pg.psql("SELECT count(*) FROM fogbench.samples") == "0");
  // Nonsense options are refused before anything is written.
  o.sample_runs = -1;
  auto bad = plant::generate_fleet(*c, o);
  REQUIRE_FALSE(bad);
  CHECK(bad.error().code == plant::PlantErrc::invalid_argument);
  CHECK(pg.psql("SELECT count(*) FROM fogbench.runs") == "12");
}
