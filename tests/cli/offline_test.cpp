// fogctl simulate / fit / verify called as functions: outputs, JSON keys, exit codes, and
// every bad input named with its place.
#include <catch2/catch.hpp>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "offline.hpp"
#include "temp_dir.hpp"

using namespace fogbench::cli;
namespace fs = std::filesystem;

namespace {

using fogbench::cli::testing::Dir;

void write(const std::string& path, const std::string& text) { std::ofstream(path) << text; }

struct Result {
  int code;
  std::string out, err;
};

Result simulate(const std::string& profile, std::uint64_t seed, const std::string& out_path, std::vector<std::string> effects = {}) {
  SimulateOptions o;
  o.profile = profile;
  o.seed = seed;
  o.output = out_path;
  o.effects = std::move(effects);
  o.coil = "lumped";  // the paper's model is the exact truth: its fit passes, a hidden effect shows
  o.quiet = true;
  std::ostringstream out, err;
  const int c = run_simulate(o, out, err);
  return {c, out.str(), err.str()};
}

Result fit(FitCommandOptions o) {
  std::ostringstream out, err;
  const int c = run_fit(o, out, err);
  return {c, out.str(), err.str()};
}

Result verify(VerifyOptions o) {
  std::ostringstream out, err;
  const int c = run_verify(o, out, err);
  return {c, out.str(), err.str()};
}

// A valid 1 Hz CSV of n rows with a gentle ramp, for error cases built by editing it.
std::string csv(std::size_t n) {
  std::string s = "time_s,gyro_dph,t1_c,t2_c\n";
  for (std::size_t i = 0; i < n; ++i) {
    const double t1 = 20.0 + (i > 600 ? 5.0 * std::sin(static_cast<double>(i - 600) / 500.0) : 0.0);
    s += std::to_string(i) + "," + std::to_string(-8.0 + 0.01 * std::sin(static_cast<double>(i) * 0.7)) + "," + std::to_string(t1) + "," +
         std::to_string(t1 + 0.1 * std::cos(static_cast<double>(i) / 300.0)) + "\n";
  }
  return s;
}

}  // namespace

TEST_CASE("fogctl: simulate, fit and verify the paper's runs end to end") {
  Dir d;
  REQUIRE(simulate("exp1", 1, d.file("e1.csv")).code == kExitOk);
  REQUIRE(simulate("exp2", 2, d.file("e2.csv")).code == kExitOk);
  FitCommandOptions f;
  f.run = d.file("e1.csv");
  f.output = d.file("m.json");
  f.json = true;
  const Result r = fit(f);
  REQUIRE(r.code == kExitOk);
  // --json prints exactly one JSON object with the documented keys.
  const auto j = nlohmann::json::parse(r.out);
  REQUIRE(j.is_object());
  for (const char* k : {"terms", "mu0", "ar", "sigma_a", "method"}) CHECK(j.contains(k));
  REQUIRE(j["terms"].size() == 2);
  for (const char* k : {"term", "lag_s", "coef"}) CHECK(j["terms"][0].contains(k));
  CHECK(j["terms"][0]["term"] == "d(T1)");
  CHECK(fs::exists(d.file("m.json")));

  VerifyOptions v;
  v.model = d.file("m.json");
  v.runs = {d.file("e2.csv")};
  v.json = true;
  const Result vr = verify(v);
  CHECK(vr.code == kExitOk);
  const auto vj = nlohmann::json::parse(vr.out);
  for (const char* k : {"est_mean", "meas_mean", "est_std", "meas_std", "comp_std", "ratio", "pass", "phases"}) CHECK(vj.contains(k));
  CHECK(vj["pass"] == true);
  CHECK(vj["ratio"].get<double>() < 0.2);

  // The human form is a table with a verdict per run.
  v.json = false;
  v.runs = {d.file("e1.csv"), d.file("e2.csv")};
  const Result table = verify(v);
  CHECK_THAT(table.out, Catch::Contains("comp/raw") && Catch::Contains("pass"));
}

TEST_CASE("fogctl verify: a run that fails its threshold exits 1") {
  Dir d;
  REQUIRE(simulate("exp1", 3, d.file("e1.csv")).code == kExitOk);
  // A gyro with a strong absolute-temperature sensitivity the paper's model lacks.
  REQUIRE(simulate("exp3", 4, d.file("e3.csv"), {"0.5*T1"}).code == kExitOk);
  FitCommandOptions f;
  f.run = d.file("e1.csv");
  f.output = d.file("m.json");
  REQUIRE(fit(f).code == kExitOk);
  VerifyOptions v;
  v.model = d.file("m.json");
  v.runs = {d.file("e3.csv")};
  const Result r = verify(v);
  CHECK(r.code == kExitFailed);
  CHECK_THAT(r.out, Catch::Contains("FAIL"));
}

TEST_CASE("fogctl: bad input gets one clear message and exit 2") {
  Dir d;
  FitCommandOptions f;
  SECTION("a missing column is named") {
    write(d.file("a.csv"), "time_s,gyro_dph,t1_c\n0,1,2\n");
    f.run = d.file("a.csv");
    const Result r = fit(f);
    CHECK(r.code == kExitError);
    CHECK_THAT(r.err, Catch::Contains("t2_c") && Catch::Contains("--map"));
  }
  SECTION("a cell that is not a number: line and column") {
    std::string text = csv(2000);
    const auto pos = text.find("\n", text.find("\n12,")) ;  // a row further down
    text.insert(text.find("\n13,") + 4, "x");
    (void)pos;
    write(d.file("b.csv"), text);
    f.run = d.file("b.csv");
    const Result r = fit(f);
    CHECK(r.code == kExitError);
    CHECK_THAT(r.err, Catch::Contains(":15:") && Catch::Contains("gyro_dph") && Catch::Contains("not a number"));
  }
  SECTION("time that goes backwards says where") {
    std::string text = csv(2000);
    const auto at = text.find("\n100,");
    text.replace(at + 1, 3, "98");
    write(d.file("c.csv"), text);
    f.run = d.file("c.csv");
    const Result r = fit(f);
    CHECK(r.code == kExitError);
    CHECK_THAT(r.err, Catch::Contains(":102:"));
  }
  SECTION("a run too short for the lags asked") {
    write(d.file("s.csv"), csv(300));
    f.run = d.file("s.csv");
    const Result r = fit(f);
    CHECK(r.code == kExitError);
    CHECK_THAT(r.err, Catch::Contains("300 samples") && Catch::Contains("too short"));
  }
  SECTION("collinear terms are named") {
    write(d.file("k.csv"), csv(3000));
    f.run = d.file("k.csv");
    f.terms = "T1 + T2 + grad";
    const Result r = fit(f);
    CHECK(r.code == kExitError);
    CHECK_THAT(r.err, Catch::Contains("collinear") && Catch::Contains("'grad'"));
  }
  SECTION("an unknown term: its position is shown") {
    write(d.file("u.csv"), csv(3000));
    f.run = d.file("u.csv");
    f.terms = "d(T1)@auto + T7";
    const Result r = fit(f);
    CHECK(r.code == kExitError);
    CHECK_THAT(r.err, Catch::Contains("unknown name 'T7'") && Catch::Contains("position 14") &&
                          Catch::Contains("             ^"));
  }
  SECTION("bad syntax") {
    write(d.file("u.csv"), csv(3000));
    f.run = d.file("u.csv");
    f.terms = "d(T1";
    const Result r = fit(f);
    CHECK(r.code == kExitError);
    CHECK_THAT(r.err, Catch::Contains("expected ')'"));
  }
  SECTION("a file that does not exist") {
    f.run = d.file("nope.csv");
    const Result r = fit(f);
    CHECK(r.code == kExitError);
    CHECK_THAT(r.err, Catch::Contains("nope.csv"));
  }
  SECTION("a model file that is not a model") {
    write(d.file("m.json"), "{\"format\": \"something else\"}");
    write(d.file("u.csv"), csv(3000));
    VerifyOptions v;
    v.model = d.file("m.json");
    v.runs = {d.file("u.csv")};
    const Result r = verify(v);
    CHECK(r.code == kExitError);
    CHECK_THAT(r.err, Catch::Contains("m.json") && Catch::Contains("format"));
  }
  SECTION("an unknown profile") {
    const Result r = simulate("exp9", 1, d.file("x.csv"));
    CHECK(r.code == kExitError);
    CHECK_THAT(r.err, Catch::Contains("exp9"));
  }
  SECTION("a bad effect") {
    const Result r = simulate("exp1", 1, d.file("x.csv"), {"0.1*T1^"});
    CHECK(r.code == kExitError);
    CHECK_THAT(r.err, Catch::Contains("--effect"));
  }
}

TEST_CASE("fogctl fit: columns of other names with --map, and uneven time only with --resample") {
  Dir d;
  std::string text = csv(3000);
  text.replace(0, text.find('\n'), "t,Rate,Tc,Tw,comment");
  // every data row gets a fifth, ignored column
  std::string with_extra;
  std::istringstream in(text);
  std::string line;
  std::getline(in, line);
  with_extra = line + "\n";
  while (std::getline(in, line)) with_extra += line + ",x\n";
  write(d.file("m.csv"), with_extra);
  FitCommandOptions f;
  f.run = d.file("m.csv");
  f.terms = "T1@auto";
  f.input.maps = {"time_s=t", "gyro_dph=Rate", "t1_c=Tc", "t2_c=Tw"};
  CHECK(fit(f).code == kExitOk);
}

TEST_CASE("fogctl fit: a CSV of a million rows imports and fits") {
  Dir d;
  {
    std::ofstream o(d.file("big.csv"));
    o << "# a million seconds of a slow thermal cycle\ntime_s,gyro_dph,t1_c,t2_c\n";
    char buf[128];
    for (int i = 0; i < 1000000; ++i) {
      const double t1 = 20.0 + 10.0 * std::sin(i / 3000.0);
      // The wall leads the centre (T2 = T1 + 0.2 cos: about 60 s ahead), as heat flows in
      // from outside; the centre leading the wall is a sensor problem the fit refuses.
      std::snprintf(buf, sizeof buf, "%d,%.4f,%.4f,%.4f\n", i, -8.0 + 0.3 * std::cos(i / 3000.0) + 0.1 * std::sin(i * 1.3), t1,
                    t1 + 0.2 * std::cos(i / 3000.0));
      o << buf;
    }
  }
  FitCommandOptions f;
  f.run = d.file("big.csv");
  f.terms = "d(T1)@auto";
  f.json = true;
  const Result r = fit(f);
  REQUIRE(r.code == kExitOk);
  CHECK(nlohmann::json::parse(r.out)["fitted_on"]["n_samples"] == 1000000);
}
