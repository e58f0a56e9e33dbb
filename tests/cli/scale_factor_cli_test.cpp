// fogctl simulate --rate-sequence and fogctl scale-factor called as functions: the mock gyro's
// true scale factor (temperature coefficient, nonlinearity, asymmetry) recovered from a
// simulated run through its CSV, the table and JSON, and bad input named by line and column.
#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "fogbench/model/scale_factor.hpp"
#include "fogbench/sim/scale_factor.hpp"
#include "offline.hpp"
#include "scale_factor.hpp"
#include "table.hpp"
#include "temp_dir.hpp"
#include "workbench.hpp"

using namespace fogbench::cli;
using Catch::Matchers::Contains;

namespace {

using fogbench::cli::testing::Dir;

struct Result {
  int code;
  std::string out, err;
};

// Settled holds at 20, 50 and -10 degC with ramps between: plateaus at three temperatures
// (each settle step is a plateau too), and ramps at +1, -2 and +1 degC/min for the
// temperature-rate term.
constexpr const char* kProfile =
    "setpoint 20 C\n"
    "hold 15 min\n"
    "ramp to 50 C at 1 C/min\n"
    "settle within 1 C on coil slope 0.01 C/min for 10 min timeout 3 h\n"
    "hold 15 min\n"
    "ramp to -10 C at 2 C/min\n"
    "settle within 1 C on coil slope 0.01 C/min for 10 min timeout 3 h\n"
    "hold 15 min\n"
    "ramp to 20 C at 1 C/min\n"
    "hold 15 min\n";
constexpr const char* kRates = "0,10,-10,100,-100,300,-300";

Result simulate(const Dir& d, const fogbench::sim::ScaleFactorTruth& truth, const std::string& rates = kRates) {
  SimulateOptions o;
  o.profile = d.write("sf.profile", kProfile);
  o.output = d.file("run.csv");
  o.rate_sequence = rates;
  o.rate_step_s = 20.0;
  o.sf_truth = truth;
  o.quiet = true;
  std::ostringstream out, err;
  const int c = run_simulate(o, out, err);
  return {c, out.str(), err.str()};
}

Result scale_factor(const std::string& run, bool json, double settle_s = 5.0) {
  ScaleFactorOptions o;
  o.run = run;
  o.json = json;
  o.settle_s = settle_s;
  std::ostringstream out, err;
  const int c = run_scale_factor(o, out, err);
  return {c, out.str(), err.str()};
}

}  // namespace

TEST_CASE("fogctl scale-factor recovers the mock gyro's temperature coefficient, nonlinearity and asymmetry", "[scale_factor]") {
  Dir d("sf");
  fogbench::sim::ScaleFactorTruth truth;
  truth.tc_ppm_per_c = 15.0;
  truth.nl_ppm = 50.0;
  truth.asymmetry_ppm = 100.0;
  auto s = simulate(d, truth);
  REQUIRE(s.code == kExitOk);
  CHECK_THAT(s.out, Contains("rate sequence"));
  auto r = scale_factor(d.file("run.csv"), true);
  INFO(r.err);
  REQUIRE(r.code == kExitOk);
  const auto j = nlohmann::json::parse(r.out);
  REQUIRE(j["plateaus"].size() == 9);  // the 4 holds, 2 settles and 3 ramps

  // The noiseless truth on a plateau's steps (the same rates in the same numbers: a plateau
  // holds a whole number of steps, not of sequences) at one temperature: what its nonlinearity
  // and asymmetry should be. The asymmetry is 100 ppm exactly: the cubic term is even in the
  // local scale factor, so both half slopes carry it alike.
  auto ideal_of = [&](const nlohmann::json& plateau) {
    fogbench::model::sf::RateRecord ideal;
    double t = 0.0;
    for (const auto& step : plateau["steps"]) {
      const double rate = step["rate_in_dps"].get<double>();
      for (int i = 0; i < 10; ++i, t += 1.0) {
        ideal.time_s.push_back(t);
        ideal.plateau.push_back(0);
        ideal.rate_in_dps.push_back(rate);
        ideal.rate_out_dps.push_back(fogbench::sim::indicated_rate_dps(truth, rate, 20.0, 0.0));
        ideal.coil_c.push_back(20.0);
      }
    }
    auto want = fogbench::model::sf::fit(ideal, {});
    REQUIRE(want);
    CHECK(want->plateaus[0].asymmetry_ppm == Approx(100.0).epsilon(1e-6));
    return want->plateaus[0].nonlinearity_ppm;
  };
  // On the settled plateaus (steps' coil temperatures within 0.1 degC: the scale factor moves
  // 1.5 ppm at most over the sequence). The noise: 0.146 deg/h white per sample over ~ 15
  // samples a step is 1e-5 deg/s, 0.04 ppm of the 300 deg/s full scale; the rare 2.5 deg/h
  // spikes add some: 1 ppm on the nonlinearity, 2 ppm on the asymmetry.
  int settled = 0;
  for (const auto& p : j["plateaus"]) {
    if (p["coil_span_c"].get<double>() > 0.1) continue;
    ++settled;
    INFO("plateau " << p["plateau"] << " at " << p["coil_c"] << " degC");
    const double nl_true = ideal_of(p);
    CHECK(nl_true > 10.0);  // the cubic term and the asymmetry's kink: not a trivial 0
    CHECK(p["nonlinearity_ppm"].get<double>() == Approx(nl_true).margin(1.0));
    CHECK(p["asymmetry_ppm"].get<double>() == Approx(100.0).margin(2.0));
  }
  CHECK(settled >= 3);
  // The temperature coefficient within three of its stated standard errors.
  const auto& tc = j["tc_ppm_per_c"];
  REQUIRE(tc["value"].is_number());
  INFO("tc " << tc["value"] << " +- " << tc["se"]);
  CHECK(tc["se"].get<double>() > 0.0);
  CHECK(std::abs(tc["value"].get<double>() - 15.0) < 3.0 * tc["se"].get<double>());
  CHECK(j["model"]["k1_ppm_per_c"]["value"].is_number());
  CHECK(j["samples_dropped"].get<int>() > 0);
}

TEST_CASE("fogctl scale-factor prints a table per plateau, the temperature sensitivity and the model form", "[scale_factor]") {
  Dir d("sf");
  fogbench::sim::ScaleFactorTruth truth;
  REQUIRE(simulate(d, truth).code == kExitOk);
  auto r = scale_factor(d.file("run.csv"), false);
  REQUIRE(r.code == kExitOk);
  CHECK_THAT(r.out, Contains("NL ppm") && Contains("asym ppm") && Contains("temperature sensitivity:") &&
                        Contains("ppm/degC") && Contains("SF(T) = SF0 (1 + k1 (T - T0) + k2 (T - T0)^2)") &&
                        Contains("first 5.0 s of each rate step dropped") && Contains("ppm of full-scale output"));
  // In a 100-column terminal every line fits (issue 28: output within 100 columns by default).
  set_output_width(100);
  auto narrow = scale_factor(d.file("run.csv"), false);
  set_output_width(0);
  REQUIRE(narrow.code == kExitOk);
  std::istringstream lines(narrow.out);
  std::size_t longest = 0;
  for (std::string line; std::getline(lines, line);) longest = std::max(longest, display_width(line));
  CHECK(longest <= 100);
  CHECK_THAT(narrow.out, Contains("note: plateau"));
}

TEST_CASE("fogctl scale-factor and simulate --rate-sequence: bad input named by line, column, plateau or item", "[scale_factor]") {
  Dir d("sf");
  SECTION("a rate sequence item that is not a number") {
    auto s = simulate(d, {}, "0,10,ten,-10");
    CHECK(s.code == kExitError);
    CHECK_THAT(s.err, Contains("--rate-sequence: rate 3: 'ten'"));
  }
  SECTION("a cell that is not a number") {
    const auto path = d.write("bad.csv", "time_s,plateau,rate_in_dps,rate_out_dps,t1_c\n0,1,0,0,20\n1,1,x,0,20\n");
    auto r = scale_factor(path, false);
    CHECK(r.code == kExitError);
    CHECK_THAT(r.err, Contains("bad.csv:3: column 3 'rate_in_dps': not a number: 'x'"));
  }
  SECTION("a missing column") {
    const auto path = d.write("bad.csv", "time_s,plateau,rate_in_dps,t1_c\n0,1,0,20\n");
    auto r = scale_factor(path, false);
    CHECK(r.code == kExitError);
    CHECK_THAT(r.err, Contains("bad.csv:1: the header has no column 'rate_out_dps'"));
  }
  SECTION("a nan and a short row") {
    CHECK_THAT(scale_factor(d.write("n.csv", "time_s,plateau,rate_in_dps,rate_out_dps,t1_c\n0,1,0,nan,20\n"), false).err,
               Contains("n.csv:2: column 4 'rate_out_dps': not a finite number"));
    CHECK_THAT(scale_factor(d.write("s.csv", "time_s,plateau,rate_in_dps,rate_out_dps,t1_c\n0,1,0,20\n"), false).err,
               Contains("s.csv:2: 4 fields, the header has 5"));
  }
  SECTION("a plateau with positive rates only") {
    std::string csv = "time_s,plateau,rate_in_dps,rate_out_dps,t1_c\n";
    for (int i = 0; i < 40; ++i) csv += std::to_string(i) + ",3," + (i < 20 ? "10" : "20") + "," + (i < 20 ? "10" : "20") + ",20\n";
    auto r = scale_factor(d.write("pos.csv", csv), false);
    CHECK(r.code == kExitError);
    CHECK_THAT(r.err, Contains("pos.csv: plateau 3: no negative input rate"));
  }
  SECTION("plateaus at rest (a run's ramps, as fogctl export writes them) are left out; none turning is an error") {
    // sf = 1 + 10 ppm/degC (T - 20): plateaus 0, 2, 4 turn at 20, 30, 40 degC; 1 and 3 are ramps at rest.
    std::string csv = "time_s,plateau,rate_in_dps,rate_out_dps,t1_c\n";
    std::string rest = csv;
    int t = 0;
    for (int p = 0; p < 5; ++p)
      for (double rate : {10.0, -10.0, 20.0, -20.0, 0.0})
        for (int k = 0; k < 10; ++k, ++t) {
          const double r = p % 2 ? 0.0 : rate;
          const double temp = 20.0 + 5.0 * p;
          const std::string row = std::to_string(t) + "," + std::to_string(p) + "," + std::to_string(r) + ",";
          csv += row + std::to_string(r * (1.0 + 10e-6 * (temp - 20.0))) + "," + std::to_string(temp) + "\n";
          rest += std::to_string(t) + "," + std::to_string(p) + ",0,0," + std::to_string(temp) + "\n";
        }
    auto r = scale_factor(d.write("ramps.csv", csv), true);
    INFO(r.err);
    REQUIRE(r.code == kExitOk);
    const auto j = nlohmann::json::parse(r.out);
    CHECK(j["plateaus"].size() == 3);
    CHECK(j["tc_ppm_per_c"]["value"].get<double>() == Approx(10.0).margin(0.05));
    auto e = scale_factor(d.write("rest.csv", rest), false);
    CHECK(e.code == kExitError);
    // The reader leaves the plateaus at rest out and says so; none left is the error.
    CHECK_THAT(e.err, Contains("rest.csv: no plateau with a rate step"));
    CHECK_THAT(e.err, Contains("the table at rest throughout"));
  }
  SECTION("a settle longer than the steps") {
    REQUIRE(simulate(d, {}).code == kExitOk);
    auto r = scale_factor(d.file("run.csv"), false, 25.0);
    CHECK(r.code == kExitError);
    CHECK_THAT(r.err, Contains("plateau 1, step 0 (0 deg/s from t = 0 s)") && Contains("no sample left after dropping the first 25 s"));
  }
  SECTION("a missing file") {
    CHECK_THAT(scale_factor(d.file("none.csv"), false).err, Contains("none.csv: cannot be read"));
  }
}

// A daemon's export (fogctl run export of a run that drove the rate table): the profile's
// setpoint step at rest (plateau 0), the hold's rate sequence (plateau 1), a second the daemon
// stored without a gyro reading (empty gyro_dph and rate_out_dps, flagged missing) and one
// without the thermistors' (empty t1_c and t2_c).
std::string daemon_export() {
  std::string csv = "# run: 7\ntime_s,gyro_dph,t1_c,t2_c,step,flags,plateau,rate_in_dps,rate_out_dps\n";
  for (int i = 0; i < 130; ++i) {
    const int plateau = i < 10 ? 0 : 1;
    const double rate = i < 10 ? 0.0 : i < 50 ? 10.0 : i < 90 ? -10.0 : 0.0;
    const double out_dps = 1.0001 * rate + 0.002;  // SF 1.0001, bias 7.2 deg/h
    const std::string t = std::to_string(i), p = std::to_string(plateau);
    if (i == 70) {
      csv += t + ",,20,20," + p + ",1," + p + ",-10,\n";
      continue;
    }
    if (i == 75) {  // the gyro read, the thermistors not
      csv += t + ",-35996.4,,," + p + ",1," + p + ",-10,-9.999\n";
      continue;
    }
    char g[64], o[64], r[32];
    std::snprintf(g, sizeof g, "%.17g", out_dps * 3600.0);
    std::snprintf(o, sizeof o, "%.17g", out_dps);
    std::snprintf(r, sizeof r, "%g", rate);
    csv += t + "," + g + ",20,20," + p + ",0," + p + "," + r + "," + o + "\n";
  }
  return csv;
}

TEST_CASE("fogctl scale-factor skips the seconds without a gyro reading and the plateaus at rest, and says so", "[scale_factor]") {
  Dir d("sf");
  const auto path = d.write("export.csv", daemon_export());
  auto j = scale_factor(path, true);
  INFO(j.err);
  REQUIRE(j.code == kExitOk);
  const auto r = nlohmann::json::parse(j.out);
  CHECK(r["skipped"]["no_gyro_reading"] == 1);
  CHECK(r["skipped"]["no_coil_reading"] == 1);
  CHECK(r["skipped"]["at_rest_plateaus"] == nlohmann::json::array({0}));
  CHECK(r["skipped"]["at_rest_rows"] == 10);
  REQUIRE(r["plateaus"].size() == 1);
  CHECK(r["plateaus"][0]["plateau"] == 1);
  CHECK(r["plateaus"][0]["scale_factor"].get<double>() == Approx(1.0001).epsilon(1e-9));
  CHECK(r["plateaus"][0]["bias_dph"].get<double>() == Approx(7.2).epsilon(1e-6));
  // The -10 deg/s step has two samples fewer: 40 - 5 settled - 2 skipped.
  CHECK(r["plateaus"][0]["steps"][1]["n_used"] == 33);
  auto t = scale_factor(path, false);
  REQUIRE(t.code == kExitOk);
  CHECK_THAT(t.out, Contains("skipped: 1 second without a gyro reading (empty rate_out_dps); 1 second without a coil "
                             "temperature (empty t1_c); plateau 0 (10 seconds) with no rate step: the table at rest "
                             "throughout"));
  SECTION("a file with no plateau that turns is an error saying what was skipped") {
    const auto rest = d.write("rest.csv", "time_s,plateau,rate_in_dps,rate_out_dps,t1_c\n0,0,0,0,20\n1,0,0,,20\n");
    auto e = scale_factor(rest, false);
    CHECK(e.code == kExitError);
    CHECK_THAT(e.err, Contains("rest.csv: no plateau with a rate step (skipped: 1 second without a gyro reading "
                               "(empty rate_out_dps); plateau 0 (1 second) with no rate step"));
  }
}

// fogctl report --scale-factor: the page carries the rate sequence's figures as fogctl
// scale-factor computes them (the same fit, the same numbers), its plateaus' table, and two
// plots (the scale factor against the coil temperature with the model form, and the steps'
// residuals against the input rate); a bad file fails before any analysis, writing nothing.
TEST_CASE("fogctl report --scale-factor: the scale factor section, its figures and plots", "[scale_factor][report]") {
  Dir d("sf");
  fogbench::sim::ScaleFactorTruth truth;
  truth.tc_ppm_per_c = 15.0;
  REQUIRE(simulate(d, truth).code == kExitOk);
  const std::string e1 = d.file("e1.csv"), m = d.file("m.json");
  {
    SimulateOptions s;
    s.profile = "exp1";
    s.output = e1;
    s.seed = 5;
    s.coil = "lumped";
    s.quiet = true;
    std::ostringstream o, e;
    REQUIRE(run_simulate(s, o, e) == kExitOk);
    FitCommandOptions f;
    f.run = e1;
    f.output = m;
    REQUIRE(run_fit(f, o, e) == kExitOk);
  }
  auto sfj = scale_factor(d.file("run.csv"), true);
  REQUIRE(sfj.code == kExitOk);
  const auto j = nlohmann::json::parse(sfj.out);

  ReportOptions r;
  r.model = m;
  r.runs = {e1};
  r.output = d.file("report.html");
  r.scale_factor = d.file("run.csv");
  std::ostringstream out, err;
  const int code = run_report(r, out, err);
  INFO(err.str());
  REQUIRE((code == kExitOk || code == kExitMarginal || code == kExitFailed));
  std::ifstream in(r.output);
  std::stringstream buf;
  buf << in.rdbuf();
  const std::string html = buf.str();
  REQUIRE(html.find("Scale factor over temperature (IEEE Std 952)") != std::string::npos);
  // The same temperature sensitivity as fogctl scale-factor's, in the page and in the summary line.
  const std::string tc = coefficient_text(
      fogbench::model::sf::Coefficient{j["tc_ppm_per_c"]["value"].get<double>(), j["tc_ppm_per_c"]["se"].get<double>(), ""}, 3, "ppm/degC");
  CHECK(html.find(tc) != std::string::npos);
  CHECK_THAT(out.str(), Contains("scale factor temperature sensitivity " + tc));
  // A table row per plateau, and the two plots: one point per plateau, one series per plateau.
  const std::size_t n_plateaus = j["plateaus"].size();
  for (const auto& p : j["plateaus"]) CHECK(html.find("<td>" + fixed(p["coil_c"].get<double>(), 2) + "</td>") != std::string::npos);
  const auto a = html.find("const DATA=");
  REQUIRE(a != std::string::npos);
  const auto end = html.find(";</script>", a);
  const auto data = nlohmann::json::parse(html.substr(a + 11, end - a - 11));
  const nlohmann::json* temp = nullptr;
  const nlohmann::json* nl = nullptr;
  for (const auto& p : data["plots"]) {
    if (p["id"] == "sf_temp") temp = &p;
    if (p["id"] == "sf_nl") nl = &p;
  }
  REQUIRE(temp);
  REQUIRE(nl);
  CHECK((*temp)["kind"] == "xy");
  CHECK((*nl)["series"].size() == n_plateaus);
  INFO(temp->dump().substr(0, 600));
  CHECK((*temp)["series"].size() == 2);

  SECTION("a bad rate-sequence file: exit 2 before the analysis, its line and column named, no page written") {
    std::ofstream(d.file("bad.csv")) << "time_s,plateau,t1_c,rate_in_dps,rate_out_dps\n0,1,20,10,x\n";
    ReportOptions b = r;
    b.scale_factor = d.file("bad.csv");
    b.output = d.file("bad.html");
    std::ostringstream o2, e2;
    CHECK(run_report(b, o2, e2) == kExitError);
    CHECK_THAT(e2.str(), Contains("--scale-factor") && Contains("bad.csv:2: column 5 'rate_out_dps': not a number: 'x'"));
    CHECK_FALSE(std::ifstream(b.output).good());
  }
}
