// fogctl's data-quality check before physics (docs/data-quality.md), its commands called as
// functions on simulated runs with faults injected into their CSV: each refused with exit 2
// naming the sensor and the interval, or cleaned with a warning that says what was done; time
// in milliseconds caught with a hint that is a command that works.
#include <catch2/catch.hpp>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "fogbench/storage/csv.hpp"
#include "offline.hpp"
#include "workbench.hpp"
#include "temp_dir.hpp"

using namespace fogbench;
using namespace fogbench::cli;
using Catch::Contains;
namespace fs = std::filesystem;

namespace {

using fogbench::cli::testing::Dir;

struct Result {
  int code;
  std::string out, err;
};

model::RunData simulated(const Dir& d, const std::string& profile, std::uint64_t seed, const std::string& coil) {
  SimulateOptions o;
  o.profile = profile;
  o.seed = seed;
  o.coil = coil;
  o.quiet = true;
  o.output = d.file(fs::path(profile).stem().string() + "-" + std::to_string(seed) + ".csv");
  std::ostringstream out, err;
  REQUIRE(run_simulate(o, out, err) == 0);
  auto r = storage::read_csv_file(o.output, {});
  REQUIRE(r);
  return *r;
}

std::string save(const Dir& d, const std::string& name, const model::RunData& r) {
  const std::string p = d.file(name);
  REQUIRE(storage::write_csv_file(p, r));
  return p;
}

Result fit(const std::string& run, const std::string& quality = "check", bool json = false, const std::string& output = "",
           const std::string& time_unit = "s", std::optional<double> resample = std::nullopt) {
  FitCommandOptions o;
  o.run = run;
  o.json = json;
  o.output = output;
  o.input.quality = quality;
  o.input.time_unit = time_unit;
  o.input.resample_s = resample;
  std::ostringstream out, err;
  const int c = run_fit(o, out, err);
  return {c, out.str(), err.str()};
}

void delay(std::vector<double>& x, std::size_t by) {
  std::vector<double> y(x.size());
  for (std::size_t i = 0; i < x.size(); ++i) y[i] = x[i >= by ? i - by : 0];
  x = y;
}

}  // namespace

TEST_CASE("fogctl fit: a clean simulated run passes the check silently", "[quality]") {
  Dir d;
  const auto run = simulated(d, "exp1", 21, "distributed");
  const auto r = fit(save(d, "clean.csv", run), "check", true);
  INFO(r.err);
  REQUIRE(r.code == 0);
  const auto j = nlohmann::json::parse(r.out);
  CHECK(j["data_quality"].empty());
  CHECK(j["identification"].is_array());
}

TEST_CASE("fogctl fit: a thermistor at -273.15 degC for 100 s is refused, or cleaned when asked", "[quality]") {
  for (const std::string sensor : {"t1_c", "t2_c"}) {
    Dir d;
    auto run = simulated(d, "exp1", 22, "lumped");
    auto& x = sensor == "t1_c" ? run.t1_c : run.t2_c;
    for (std::size_t i = 2000; i < 2100; ++i) x[i] = -273.15;
    const std::string path = save(d, "open.csv", run), model = d.file("m.json");
    const auto r = fit(path, "check", false, model);
    INFO(r.err);
    CHECK(r.code == 2);
    CHECK(r.out.empty());
    CHECK_FALSE(fs::exists(model));
    CHECK_THAT(r.err, Contains(sensor == "t1_c" ? "T1 out_of_range at 2000..2099 s" : "T2 out_of_range at 2000..2099 s"));
    CHECK_THAT(r.err, Contains("-273.15 degC") && Contains("--quality clean"));
    // Cleaned: the warning says what was done; the model is the clean run's within 3 se
    // (100 s bridged on a 1 degC/min ramp of exp1, 2000..2100 s: linear, exact but for noise).
    const auto c = fit(path, "clean", true);
    INFO(c.err);
    REQUIRE(c.code == 0);
    const auto j = nlohmann::json::parse(c.out);
    REQUIRE(j["data_quality"].size() == 1);
    CHECK(j["data_quality"][0]["action"] == "cleaned");
    CHECK(j["data_quality"][0]["start_s"] == 2000);
    CHECK(j["data_quality"][0]["end_s"] == 2099);
    const auto t = fit(save(d, "text.csv", run), "clean");
    CHECK_THAT(t.out, Contains("warning: ") && Contains("cleaned") && Contains("100 samples flagged out of range"));
    auto ref = simulated(d, "exp1", 22, "lumped");
    const auto base = nlohmann::json::parse(fit(save(d, "ref.csv", ref), "check", true).out);
    for (std::size_t k = 0; k < 2; ++k) {
      const double a = j["terms"][k]["coef"], b = base["terms"][k]["coef"], se = base["terms"][k]["se"];
      CHECK(std::abs(a - b) < 3 * se);
    }
  }
}

TEST_CASE("fogctl fit: a 1e6 gyro spike is cleaned with a warning, and the fit is the clean one", "[quality]") {
  Dir d;
  auto run = simulated(d, "exp1", 23, "distributed");
  const auto base = nlohmann::json::parse(fit(save(d, "ref.csv", run), "check", true).out);
  run.gyro_dph[3000] = 1e6;
  const auto r = fit(save(d, "spike.csv", run), "check", true);
  INFO(r.err);
  REQUIRE(r.code == 0);
  const auto j = nlohmann::json::parse(r.out);
  REQUIRE(j["data_quality"].size() == 1);
  CHECK(j["data_quality"][0]["sensor"] == "gyro");
  CHECK(j["data_quality"][0]["kind"] == "spike");
  CHECK(j["data_quality"][0]["start_s"] == 3000);
  // The standard errors are the clean run's (the spike had given se 16,925 on d(T1)): within 5%.
  for (std::size_t k = 0; k < 2; ++k) CHECK(double(j["terms"][k]["se"]) == Approx(double(base["terms"][k]["se"])).epsilon(0.05));
  const auto t = fit(save(d, "spike2.csv", run));
  CHECK_THAT(t.out, Contains("warning: ") && Contains("cleaned gyro spike at 3000..3000 s"));
}

TEST_CASE("fogctl fit: time in milliseconds is refused with a command that works, and read with --time-unit ms", "[quality]") {
  Dir d;
  auto run = simulated(d, "exp1", 24, "distributed");
  const auto base = fit(save(d, "s.csv", run), "check", true);
  REQUIRE(base.code == 0);
  for (auto& t : run.time_s) t *= 1000.0;
  const std::string path = save(d, "time_ms.csv", run);
  const auto r = fit(path);
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Contains("milliseconds") && Contains("fogctl fit " + path + " --time-unit ms"));
  // fogctl's old hint, --resample 1, would have made a 62-day run of 5.4 M interpolated samples.
  const auto resampled = fit(path, "check", false, "", "s", 1.0);
  CHECK(resampled.code == 2);
  CHECK_THAT(resampled.err, Contains("--time-unit ms"));
  // The command the hint names works, and gives the model of the run in seconds.
  const auto ok = fit(path, "check", true, "", "ms");
  INFO(ok.err);
  REQUIRE(ok.code == 0);
  const auto a = nlohmann::json::parse(ok.out), b = nlohmann::json::parse(base.out);
  CHECK(a["terms"][0]["coef"] == b["terms"][0]["coef"]);
  CHECK(a["fitted_on"]["duration_s"] == b["fitted_on"]["duration_s"]);
}

TEST_CASE("fogctl fit and diagnose: a thermistor lagging a minute is a sensor problem, not physics", "[quality]") {
  Dir d;
  auto run = simulated(d, "exp1", 25, "distributed");
  const std::string clean = save(d, "clean.csv", run), model = d.file("m.json");
  REQUIRE(fit(clean, "check", false, model).code == 0);
  delay(run.t1_c, 60);
  const std::string lag = save(d, "lag.csv", run);
  const auto r = fit(lag);
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Contains("T1 lag at 0..5399 s") && Contains("a sensor problem"));
  DiagnoseCommandOptions o;
  o.model = model;
  o.runs = {lag};
  o.search = "library";
  o.max_terms = 1;
  {
    std::ostringstream out, err;
    CHECK(run_diagnose(o, out, err) == 2);
    CHECK_THAT(err.str(), Contains("a sensor problem") && Contains("T1 lag"));
  }
  // --quality warn runs the search, but the answer is the sensor problem, and the model is not adequate.
  o.input.quality = "warn";
  o.json = true;
  std::ostringstream out, err;
  CHECK(run_diagnose(o, out, err) == 1);
  const auto j = nlohmann::json::parse(out.str());
  CHECK(j["sensor_problem"] == true);
  CHECK(j["adequate"] == false);
  CHECK_THAT(j["headline"].get<std::string>(), Contains("a sensor problem: T1 lag"));
}

TEST_CASE("fogctl verify: a stuck thermistor is refused naming it and its interval", "[quality]") {
  Dir d;
  auto run = simulated(d, "exp2", 26, "distributed");
  const std::string model = d.file("m.json");
  REQUIRE(fit(save(d, "clean.csv", run), "check", false, model).code == 0);
  for (std::size_t i = 700; i < 1000; ++i) run.t2_c[i] = run.t2_c[700];
  VerifyOptions o;
  o.model = model;
  o.runs = {save(d, "stuck.csv", run)};
  std::ostringstream out, err;
  CHECK(run_verify(o, out, err) == 2);
  CHECK_THAT(err.str(), Contains("T2 stuck at 700..999 s"));
  o.input.quality = "clean";
  std::ostringstream out2, err2;
  CHECK(run_verify(o, out2, err2) != 2);
  CHECK_THAT(out2.str(), Contains("cleaned T2 stuck at 700..999 s"));
}

TEST_CASE("fogctl fit: a hold-only run says its coefficients are not identified", "[quality]") {
  Dir d;
  const std::string profile = d.file("hold.profile");
  std::ofstream(profile) << "setpoint 20 C\nhold 25 min\n";
  auto run = simulated(d, profile, 27, "distributed");
  const auto r = fit(save(d, "hold.csv", run), "check", true);
  INFO(r.err);
  REQUIRE(r.code == 0);
  const auto j = nlohmann::json::parse(r.out);
  std::string all;
  for (const auto& w : j["identification"]) all += w.get<std::string>() + "\n";
  CHECK_THAT(all, Contains("no temperature excitation"));
  CHECK_THAT(fit(save(d, "hold2.csv", run)).out, Contains("warning: not identified:"));
}

TEST_CASE("fogctl diagnose and lineage: runs of two gyros given as one are refused, naming each serial", "[quality]") {
  Dir d;
  const auto a = simulated(d, "exp1", 28, "distributed"), b = simulated(d, "exp2", 29, "distributed");
  const std::string model = d.file("m.json");
  const std::string pa = save(d, "a.csv", a);
  REQUIRE(fit(pa, "check", false, model).code == 0);
  // The run's identity as fogctl run export writes it (docs/csv.md): `# serial: ...` above the header.
  auto with_serial = [&](const std::string& name, const model::RunData& r, const std::string& serial) {
    const std::string p = d.file(name);
    std::ofstream(p) << "# software_version: 0.1.0\n# serial: " << serial << "\n" << storage::to_csv(r);
    return p;
  };
  const std::string one = with_serial("one.csv", a, "FOG-0001"), other = with_serial("other.csv", b, "FOG-0002");
  DiagnoseCommandOptions o;
  o.model = model;
  o.runs = {one, other};
  o.search = "library";
  o.max_terms = 1;
  std::ostringstream out, err;
  CHECK(run_diagnose(o, out, err) == 2);
  CHECK_THAT(err.str(), Contains(one + " is FOG-0001") && Contains(other + " is FOG-0002"));
  LineageOptions l;
  l.model = model;
  l.runs = {one, other};
  std::ostringstream out2, err2;
  CHECK(run_lineage(l, out2, err2) == 2);
  CHECK_THAT(err2.str(), Contains("different gyros"));
  // One serial: no complaint.
  l.runs = {one, with_serial("again.csv", b, "FOG-0001")};
  std::ostringstream out3, err3;
  CHECK(run_lineage(l, out3, err3) == 0);
}
