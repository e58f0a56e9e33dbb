// fogctl fleet called as a function (cli/fleet.hpp) against a generated plant in a real
// PostgreSQL: tables, --json, the HTML report, the filters, and the refusals with exit 2.
#include <catch2/catch.hpp>

#include <fstream>
#include <set>
#include <sstream>

#include <nlohmann/json.hpp>

#include "fleet.hpp"
#include "fogbench/plant/generate.hpp"
#include "pg_server.hpp"

using namespace fogbench;

namespace {
struct Out {
  int code = -1;
  std::string out, err;
};
Out fleet(const std::string& cmd, const cli::FleetOptions& o) {
  std::ostringstream out, err;
  Out r;
  r.code = cli::run_fleet(cmd, o, out, err);
  r.out = out.str();
  r.err = err.str();
  return r;
}
}  // namespace

TEST_CASE("fogctl fleet: serials, history, dist and spc with --json and --html on a generated plant, and its refusals") {
  test::PgServer pg;
  cli::FleetOptions o;
  o.db = pg.conninfo();
  // Before any bench wrote: the reader says so.
  auto empty = fleet("serials", o);
  CHECK(empty.code == cli::kExitError);
  CHECK_THAT(empty.err, Catch::Contains("no fogbench schema"));

  auto c = plant::Connection::open(pg.conninfo(), true);
  REQUIRE(c);
  plant::GenerateOptions g;
  g.runs = 400;
  g.lots = 4;
  g.shifted_lot = 3;
  g.outliers = 2;
  g.seed = 3;
  g.sample_runs = 0;  // the statistics read no samples
  auto gen = plant::generate_fleet(*c, g);
  REQUIRE(gen);

  auto serials = fleet("serials", o);
  REQUIRE(serials.code == 0);
  CHECK_THAT(serials.out, Catch::Contains("800 serials"));
  o.json = true;
  o.filter.lot = "LOT-1001";
  serials = fleet("serials", o);
  REQUIRE(serials.code == 0);
  CHECK(nlohmann::json::parse(serials.out)["serials"].size() == 200);
  o.filter.lot.reset();

  o.serial = gen->outlier_serials.front();
  auto history = fleet("history", o);
  REQUIRE(history.code == 0);
  auto hj = nlohmann::json::parse(history.out);
  REQUIRE(hj["runs"].size() == 1);
  CHECK(hj["runs"][0]["figures"].contains("model:d(T1)"));

  o.figures = {"d(T1)"};
  o.by = "lot";
  auto dist = fleet("dist", o);
  REQUIRE(dist.code == 0);
  CHECK(nlohmann::json::parse(dist.out)["figures"]["d(T1)"].size() == 4);

  o.baseline_n = 200;
  o.compare = gen->shifted_lot + ",LOT-1000";
  const auto html = pg.dir() / "fleet.html";
  o.html = html.string();
  auto spc = fleet("spc", o);
  REQUIRE(spc.code == 0);
  auto sj = nlohmann::json::parse(spc.out);
  REQUIRE(sj["charts"].size() == 1);
  const auto& chart = sj["charts"][0];
  CHECK(chart["baseline"].get<std::string>().starts_with("the first 200 values"));
  std::set<std::string> flagged;
  for (const auto& u : chart["flagged_units"]) flagged.insert(u["serial"].get<std::string>());
  for (const auto& s : gen->outlier_serials) CHECK(flagged.contains(s));
  CHECK(chart["flagged_lots"] == nlohmann::json::array({gen->shifted_lot}));
  CHECK(chart["lots"].size() == 4);
  CHECK(chart["lot_comparison"]["low"].get<double>() > 0);
  std::ifstream f(html);
  std::stringstream ss;
  ss << f.rdbuf();
  CHECK_THAT(ss.str(), Catch::Contains("uPlot"));
  CHECK_THAT(ss.str(), Catch::Contains(gen->outlier_serials.front()));
  CHECK_THAT(ss.str(), Catch::Contains("Lots out of limits"));
  // The table form names the flagged units and the comparison.
  o.json = false;
  o.html.clear();
  spc = fleet("spc", o);
  REQUIRE(spc.code == 0);
  CHECK_THAT(spc.out, Catch::Contains("flagged units (beyond the limits)"));
  CHECK_THAT(spc.out, Catch::Contains("(Welch, "));
  CHECK_THAT(spc.out, Catch::Contains("lots out of limits (lot mean"));

  // Refusals: exit 2, each named.
  cli::FleetOptions bad = o;
  bad.db.clear();
  CHECK_THAT(fleet("spc", bad).err, Catch::Contains("exactly one of --db CONNSTR or --service NAME"));
  bad = o;
  bad.compare = "LOT-1000";
  CHECK_THAT(fleet("spc", bad).err, Catch::Contains("--compare: expected two lots"));
  bad = o;
  bad.compare = "LOT-1000,NO-SUCH-LOT";
  CHECK_THAT(fleet("spc", bad).err, Catch::Contains("'NO-SUCH-LOT' (0 values)"));
  bad = o;
  bad.db = pg.tcp_conninfo("wrong");
  auto refused = fleet("serials", bad);
  CHECK(refused.code == cli::kExitError);
  CHECK_THAT(refused.err, Catch::Contains("password authentication failed"));
  bad = o;
  bad.figures = {"no-such-figure"};
  CHECK_THAT(fleet("spc", bad).err, Catch::Contains("no values of figure 'no-such-figure'"));
}

TEST_CASE("fogctl fleet generate: a demonstration plant that spc then finds (its shifted lot and outliers), the same seed the same plant, and each bad option named") {
  test::PgServer pg;
  cli::FleetOptions o;
  o.db = pg.conninfo();
  o.gen_runs = 120;
  o.gen_lots = 4;
  o.gen_outliers = 2;
  o.gen_sample_runs = 3;
  o.gen_samples_per_unit = 50;
  o.gen_seed = 9;
  o.json = true;
  auto g = fleet("generate", o);
  REQUIRE(g.code == cli::kExitOk);
  const auto j = nlohmann::json::parse(g.out)["generated"];
  CHECK(j["runs"] == 120);
  CHECK(j["units"] == 240);
  CHECK(j["samples"] == 3 * 2 * 50);
  CHECK(j["shifted_lot"].get<std::string>().rfind("LOT-", 0) == 0);
  REQUIRE(j["outlier_serials"].size() == 2);

  // What it planted is what the charts find: every outlier serial is flagged.
  o.figures = {"d(T1)"};
  auto spc = fleet("spc", o);
  REQUIRE(spc.code == cli::kExitOk);
  const auto sj = nlohmann::json::parse(spc.out);
  std::set<std::string> flagged;
  for (const auto& u : sj["charts"][0]["flagged_units"]) flagged.insert(u["serial"].get<std::string>());
  CHECK(sj["charts"][0]["flagged_lots"] == nlohmann::json::array({j["shifted_lot"]}));

  // The charts as a quality engineer reads them (issue 28, point 4): run-end dates on the x axis,
  // the figure's unit, every rule's signals marked and listed, a per-lot view; drawn by headless
  // Chromium (its DOM after the scripts ran).
  const auto html = pg.dir() / "generated.html";
  o.html = html.string();
  REQUIRE(fleet("spc", o).code == cli::kExitOk);
  o.html.clear();
  std::stringstream page;
  page << std::ifstream(html).rdbuf();
  const std::string p = page.str();
  CHECK_THAT(p, Catch::Contains("<h2>d(T1) (deg/h per degC/min)</h2>"));
  CHECK_THAT(p, Catch::Contains("<table class=signals>"));
  CHECK_THAT(p, Catch::Contains("<td>1</td><td>one value beyond 3 sigma, above</td>"));
  for (const auto& s : j["outlier_serials"]) CHECK_THAT(p, Catch::Contains("<td>" + s.get<std::string>() + "</td>"));
  CHECK_THAT(p, Catch::Contains("<table class=lots>"));
  CHECK_THAT(p, Catch::Contains("<td>" + j["shifted_lot"].get<std::string>() + "</td>"));
  CHECK_THAT(p, Catch::Contains("out of limits</b>"));
  CHECK_THAT(p, Catch::Contains("\"t\":[1767"));  // 2026's run ends, as seconds since 1970
  REQUIRE(std::system("command -v chromium >/dev/null 2>&1") == 0);  // scripts/deps installs it
  const auto dom = pg.dir() / "dom.html";
  const std::string cmd = "timeout 120 chromium --headless --no-sandbox --disable-gpu --no-first-run --disable-sync "
                          "--disable-background-networking --user-data-dir=" + (pg.dir() / "chrome").string() +
                          " --dump-dom file://" + html.string() + " >" + dom.string() + " 2>" + (pg.dir() / "chrome.err").string();
  REQUIRE(std::system(cmd.c_str()) == 0);
  std::stringstream drawn;
  drawn << std::ifstream(dom).rdbuf();
  const std::string d = drawn.str();
  INFO(d.substr(0, 2000));
  CHECK_THAT(d, Catch::Contains("d(T1): individuals"));
  CHECK_THAT(d, Catch::Contains("d(T1): moving range"));
  CHECK_THAT(d, Catch::Contains("d(T1): lot means"));
  CHECK_THAT(d, Catch::Contains(">rule 1<"));     // the legend of rule 1's markers
  CHECK_THAT(d, Catch::Contains(">run end<"));    // dates on the x axis
  CHECK_THAT(d, Catch::Contains(">lot out of limits<"));
  for (const auto& s : j["outlier_serials"]) CHECK(flagged.count(s.get<std::string>()) == 1);

  // Again with the same seed: the same plant (replaced, not added to).
  auto again = fleet("generate", o);
  REQUIRE(again.code == cli::kExitOk);
  CHECK(nlohmann::json::parse(again.out)["generated"] == j);
  o.json = false;
  auto serials = fleet("serials", o);
  REQUIRE(serials.code == cli::kExitOk);
  CHECK_THAT(serials.out, Catch::Contains("240 serials"));
  // The human summary names what to look for.
  auto text = fleet("generate", o);
  REQUIRE(text.code == cli::kExitOk);
  CHECK_THAT(text.out, Catch::Contains("shifted lot"));
  CHECK_THAT(text.out, Catch::Contains(j["outlier_serials"][0].get<std::string>()));

  // Bad options: named, exit 2, nothing written.
  auto bad = o;
  bad.gen_lots = 0;
  auto r = fleet("generate", bad);
  CHECK(r.code == cli::kExitError);
  CHECK_THAT(r.err, Catch::Contains("--lots"));
  bad = o;
  bad.gen_lots = 500;
  r = fleet("generate", bad);
  CHECK(r.code == cli::kExitError);
  CHECK_THAT(r.err, Catch::Contains("--lots: expected 1 to --runs (120"));
  bad = o;
  bad.gen_sample_runs = -1;
  CHECK_THAT(fleet("generate", bad).err, Catch::Contains("--sample-runs"));
  bad = o;
  bad.service = "x";
  CHECK_THAT(fleet("generate", bad).err, Catch::Contains("exactly one of --db"));
  CHECK_THAT(fleet("serials", o).out, Catch::Contains("240 serials"));
}
