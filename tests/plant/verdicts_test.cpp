// The p-charts of verdicts per bench per period (plant/verdicts.hpp): the binomial limits and the
// grouping by hand, then a generated plant in a real PostgreSQL where one bench was planted with
// extra marginal verdicts: that bench is flagged, the others not; through `fogctl fleet spc` too
// (table, --json, --html).
#include <catch2/catch.hpp>

#include <cmath>
#include <fstream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "fleet.hpp"
#include "fogbench/plant/generate.hpp"
#include "fogbench/plant/verdicts.hpp"
#include "pg_server.hpp"

using namespace fogbench;

TEST_CASE("p-chart: binomial limits, periods and the flagging by hand") {
  // p-bar 0.1, n 100: sigma sqrt(0.1 * 0.9 / 100) = 0.03; limits 0.01 .. 0.19.
  auto l = plant::spc::p_limits(0.1, 100);
  CHECK(l.lcl == Approx(0.01));
  CHECK(l.ucl == Approx(0.19));
  // n 25: sigma 0.06, the lower limit clipped at 0.
  l = plant::spc::p_limits(0.1, 25);
  CHECK(l.lcl == 0);
  CHECK(l.ucl == Approx(0.28));
  CHECK(plant::period_of("2026-03-04T10:00:00Z", "month") == "2026-03");
  CHECK(plant::period_of("2026-03-04T10:00:00Z", "day") == "2026-03-04");
  CHECK(plant::period_of("2026-03-04T10:00:00Z", "week") == "2026-03-02/w");  // a Wednesday
  CHECK(plant::period_of("2026-03-01T10:00:00Z", "week") == "2026-02-23/w");  // a Sunday
  CHECK(plant::period_of("2026-03-02T00:00:00Z", "week") == "2026-03-02/w");  // a Monday

  // Bench A in January: 100 verdicts, 10 marginal (the baseline: p-bar 0.1). February: A 100
  // with 10 marginal (in), B 100 with 20 (above 0.19), C 100 with none (below 0.01).
  std::vector<plant::VerdictValue> v;
  auto add = [&](const std::string& bench, const std::string& at, int n, int marginal) {
    for (int i = 0; i < n; ++i) v.push_back({bench, 1, 0, "S", std::nullopt, at, i < marginal ? "marginal" : "pass"});
  };
  add("A", "2026-01-10T00:00:00Z", 100, 10);
  add("A", "2026-02-10T00:00:00Z", 100, 10);
  add("B", "2026-02-10T00:00:00Z", 100, 20);
  add("C", "2026-02-10T00:00:00Z", 100, 0);
  plant::Baseline b;
  b.first_n = 100;
  auto ch = plant::proportion_chart(v, "marginal", b);
  REQUIRE(ch);
  CHECK(ch->p_bar == Approx(0.1));
  CHECK(ch->baseline_n == 100);
  REQUIRE(ch->groups.size() == 4);
  CHECK(ch->groups[0].period == "2026-01");
  CHECK(ch->groups[0].side == 0);
  CHECK(ch->groups[2].bench == "B");
  CHECK(ch->groups[2].p == Approx(0.2));
  CHECK(ch->groups[2].ucl == Approx(0.19));
  CHECK(ch->groups[2].side == 1);
  CHECK(ch->groups[3].side == -1);
  CHECK(ch->flagged_benches == std::vector<std::string>{"B", "C"});
  // The same by time window; an empty window and unknown names are refused.
  plant::Baseline jan;
  jan.from = "2026-01-01";
  jan.to = "2026-02-01";
  auto byTime = plant::proportion_chart(v, "marginal", jan);
  REQUIRE(byTime);
  CHECK(byTime->baseline_n == 100);
  CHECK(byTime->p_bar == Approx(0.1));
  jan.from = "2027-01-01";
  jan.to.reset();
  auto none = plant::proportion_chart(v, "marginal", jan);
  REQUIRE_FALSE(none);
  CHECK_THAT(none.error(), Catch::Contains("holds no verdicts"));
  CHECK_THAT(plant::proportion_chart(v, "marginal", b, "year").error(), Catch::Contains("--period"));
  CHECK_THAT(plant::proportion_chart(v, "maybe", b).error(), Catch::Contains("'maybe'"));
}

TEST_CASE("p-chart: on a generated plant the bench planted with extra marginal verdicts is flagged, the others not") {
  test::PgServer pg;
  auto c = plant::Connection::open(pg.conninfo(), true);
  REQUIRE(c);
  plant::GenerateOptions o;
  o.runs = 4000;  // every 1800 s: January to March 2026
  o.lots = 8;
  o.shifted_lot = 5;
  o.outliers = 2;
  o.sample_runs = 0;
  o.seed = 5;
  o.marginal_rate = 0.05;
  o.fail_rate = 0.01;
  o.marginal_bench = 3;
  o.marginal_bench_rate = 0.20;
  o.marginal_from_run = 2000;  // from mid-February on
  auto g = plant::generate_fleet(*c, o);
  REQUIRE(g);
  CHECK(g->marginal_bench == "gen-bench-3");

  auto v = plant::verdict_values(*c, {});
  REQUIRE(v);
  REQUIRE(v->size() == 8000);
  plant::Baseline b;
  b.first_n = 4000;  // the runs before the planted ones
  auto m = plant::proportion_chart(*v, "marginal", b);
  REQUIRE(m);
  CHECK(m->p_bar > 0.03);
  CHECK(m->p_bar < 0.07);
  REQUIRE(m->groups.size() == 12);  // 3 months x 4 benches
  CHECK(m->flagged_benches == std::vector<std::string>{"gen-bench-3"});
  for (const auto& gr : m->groups) {
    INFO(gr.bench << " " << gr.period << " p " << gr.p << " limits " << gr.lcl << " .. " << gr.ucl);
    if (gr.bench == "gen-bench-3" && gr.period == "2026-03") CHECK(gr.side == 1);
    if (gr.bench != "gen-bench-3") CHECK(gr.side == 0);
  }
  auto f = plant::proportion_chart(*v, "fail", b);
  REQUIRE(f);
  CHECK(f->flagged_benches.empty());

  // Through fogctl fleet spc: the JSON, the table and the HTML report name the bench.
  cli::FleetOptions fo;
  fo.db = pg.conninfo();
  fo.figures = {"mu0"};
  fo.p_baseline_n = 4000;
  fo.json = true;
  fo.html = (pg.dir() / "fleet.html").string();
  std::ostringstream out, err;
  REQUIRE(cli::run_fleet("spc", fo, out, err) == 0);
  auto j = nlohmann::json::parse(out.str());
  REQUIRE(j["proportions"].size() == 2);
  CHECK(j["proportions"][0]["verdict"] == "marginal");
  CHECK(j["proportions"][0]["flagged_benches"] == nlohmann::json::array({"gen-bench-3"}));
  CHECK(j["proportions"][1]["verdict"] == "fail");
  CHECK(j["proportions"][1]["flagged_benches"].empty());
  CHECK(j["flagged_benches"] == nlohmann::json::array({"gen-bench-3"}));
  std::ifstream h(fo.html);
  std::stringstream hs;
  hs << h.rdbuf();
  CHECK_THAT(hs.str(), Catch::Contains("marginal verdicts per bench per month (p-chart)"));
  CHECK_THAT(hs.str(), Catch::Contains("class=out"));
  fo.json = false;
  fo.html.clear();
  std::ostringstream text;
  REQUIRE(cli::run_fleet("spc", fo, text, err) == 0);
  CHECK_THAT(text.str(), Catch::Contains("marginal verdicts per bench per month (p-chart)"));
  CHECK_THAT(text.str(), Catch::Contains("benches out of limits: gen-bench-3"));
  CHECK_THAT(text.str(), Catch::Contains("ABOVE"));
  fo.period = "fortnight";
  std::ostringstream o2, e2;
  CHECK(cli::run_fleet("spc", fo, o2, e2) == cli::kExitError);
  CHECK_THAT(e2.str(), Catch::Contains("--period: expected month, week or day"));
}
