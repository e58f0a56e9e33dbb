// The fleet's control charts on a generated plant in a real PostgreSQL (issue 14, point 5): the
// SPC flags the planted outlier units and no others, the shifted lot stands out in Welch's
// comparison, and the figures not planted flag nothing.
#include <catch2/catch.hpp>

#include <algorithm>
#include <set>

#include "fogbench/plant/fleet_spc.hpp"
#include "fogbench/plant/generate.hpp"
#include "pg_server.hpp"

using namespace fogbench;

TEST_CASE("fleet: on a generated plant the SPC flags the planted units and the shifted lot, and nothing else") {
  test::PgServer pg;
  auto c = plant::Connection::open(pg.conninfo(), true);
  REQUIRE(c);
  plant::GenerateOptions o;
  o.runs = 2000;
  o.lots = 10;
  o.shifted_lot = 7;
  o.shift_sigma = 1.0;
  o.outliers = 4;
  o.sample_runs = 2;
  o.samples_per_unit = 500;
  o.seed = 11;
  auto g = plant::generate_fleet(*c, o);
  REQUIRE(g);
  CHECK(g->runs == 2000);
  CHECK(g->units == 4000);
  CHECK(g->samples == 2 * 2 * 500);
  REQUIRE(g->outlier_serials.size() == 4);
  // Generating again replaces: the same counts.
  REQUIRE(plant::generate_fleet(*c, o));
  CHECK(pg.psql("SELECT count(*) FROM fogbench.units") == "4000");

  auto values = plant::figure_values(*c, "d(T1)", {});
  REQUIRE(values);
  REQUIRE(values->size() == 4000);
  CHECK(std::is_sorted(values->begin(), values->end(),
                       [](const auto& a, const auto& b) { return a.ended_at < b.ended_at; }));
  plant::Baseline b;
  b.first_n = 1000;
  auto f = plant::figure_spc("d(T1)", *values, b);
  REQUIRE(f);
  std::set<std::string> flagged;
  int false_positives = 0;
  for (auto i : f->flagged_units) {
    const auto& v = f->values[i];
    const bool planted = std::count(g->outlier_serials.begin(), g->outlier_serials.end(), v.serial) > 0;
    // Anything flagged is planted: an outlier or a unit of the shifted lot (shifted by 1 sigma,
    // some of its units lie beyond 3 sigma: true signals of the shift).
    INFO(v.serial << " " << v.lot.value_or("-") << " " << v.value);
    CHECK((planted || v.lot == g->shifted_lot));
    false_positives += !(planted || v.lot == g->shifted_lot);
    flagged.insert(v.serial);
  }
  // The generator truncates natural values at 2.5 sigma: no unit beyond 3 sigma is natural, so
  // the expected count of false positives is 0, not the 0.27% of an untruncated normal law.
  CHECK(false_positives == 0);
  for (const auto& s : g->outlier_serials) CHECK(flagged.contains(s));
  // The shifted lot, and no other, is out of limits on the lot means (without being told which).
  CHECK(f->flagged_lots == std::vector<std::string>{g->shifted_lot});
  REQUIRE(f->lots.size() == 10);
  for (const auto& l : f->lots) {
    INFO(l.lot << " mean " << l.mean << " limits " << l.lcl << " .. " << l.ucl << " z " << l.z);
    if (l.lot == g->shifted_lot) CHECK(l.z > 10);  // 1 sigma on 400 units: some 20 standard errors
    else CHECK(std::abs(l.z) < 3);
  }
  // The shifted lot: Welch's interval against an unshifted lot holds the planted shift (1 sigma
  // = 0.30) and not 0; two unshifted lots differ by less than 4 standard errors.
  auto shifted = plant::compare_lots(f->values, g->shifted_lot, "LOT-1002");
  REQUIRE(shifted);
  CHECK(shifted->low > 0);
  CHECK(shifted->low < 0.30);
  CHECK(shifted->high > 0.30);
  auto same = plant::compare_lots(f->values, "LOT-1001", "LOT-1002");
  REQUIRE(same);
  CHECK(std::abs(same->diff) < 4 * same->se);
  // The figures nothing was planted in flag no unit.
  for (const char* name : {"mu0", "grad", "sigma_a", "ratio", "comp_std"}) {
    auto v = plant::figure_values(*c, name, {});
    REQUIRE(v);
    auto s = plant::figure_spc(name, *v, b);
    REQUIRE(s);
    INFO(name);
    CHECK(s->flagged_units.empty());
    CHECK(s->flagged_lots.empty());
  }
  // Filters: one lot, one bench; a baseline window that holds nothing is a clear error.
  plant::FleetFilter lot;
  lot.lot = g->shifted_lot;
  CHECK(plant::figure_values(*c, "d(T1)", lot)->size() == 400);
  plant::FleetFilter bench;
  bench.bench = "gen-bench-2";
  CHECK(plant::figure_values(*c, "mu0", bench)->size() == 1000);
  plant::Baseline none;
  none.from = "2030-01-01";
  auto bad = plant::figure_spc("d(T1)", *values, none);
  REQUIRE_FALSE(bad);
  CHECK_THAT(bad.error(), Catch::Contains("holds 0 values"));
  auto d = plant::distribution(*values, "lot");
  REQUIRE(d);
  CHECK(d->size() == 10);
}
