// fogctl allan called as a function: the holds of a run found and analysed, the noise terms of
// a series with known white noise recovered, and bad input refused with exit 2.
#include <catch2/catch.hpp>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>

#include "allan.hpp"
#include "temp_dir.hpp"

using namespace fogbench::cli;
namespace fs = std::filesystem;

namespace {

using fogbench::cli::testing::Dir;

struct Result {
  int code;
  std::string out, err;
};

Result allan(AllanOptions o) {
  std::ostringstream out, err;
  const int c = run_allan(o, out, err);
  return {c, out.str(), err.str()};
}

// A run of 3 phases: hold (4,000 s), a 1,000 s heating ramp, hold (2,000 s); white rate noise of
// s_w deg/h per second on a bias, and a drift of 0.5 deg/h per degC/min during the ramp only.
std::string write_run(const fs::path& dir, double s_w_dph) {
  const auto path = (dir / "holds.csv").string();
  std::ofstream f(path);
  f << "time_s,gyro_dph,t1_c,t2_c,phase\n";
  std::mt19937_64 engine(5);
  std::normal_distribution<double> normal(0.0, s_w_dph);
  for (int t = 0; t < 7000; ++t) {
    const bool ramp = t >= 4000 && t < 5000;
    const double temp_c = 20.0 + (t < 4000 ? 0.0 : t < 5000 ? (t - 4000) / 60.0 : 1000.0 / 60.0);
    f << t << "," << 3.0 + (ramp ? 0.5 : 0.0) + normal(engine) << "," << temp_c << "," << temp_c << ","
      << (ramp ? "heating" : "hold") << "\n";
  }
  return path;
}

}  // namespace

TEST_CASE("fogctl allan: each hold analysed apart, white noise read as angle random walk", "[cli][allan]") {
  Dir d;
  AllanOptions o;
  o.run = write_run(d.path, 0.3);
  o.json = true;
  const auto r = allan(o);
  REQUIRE(r.code == kExitOk);
  const auto j = nlohmann::json::parse(r.out);
  REQUIRE(j["series"].size() == 2);  // the ramp is not analysed
  CHECK(j["series"][0]["series"] == "hold 1");
  CHECK(j["series"][0]["from_s"] == 0.0);
  CHECK(j["series"][0]["to_s"] == 3999.0);
  CHECK(j["series"][1]["from_s"] == 5000.0);
  CHECK(j["series"][1]["samples"] == 2000);
  // White noise of 0.3 deg/h per 1 s sample: N = 0.3 (deg/h) sqrt(s) = 0.3/60 deg/sqrt(h);
  // read over taus 1..8 s on 4,000 samples, the interval is ~2 %.
  CHECK(j["series"][0]["arw_deg_per_sqrt_h"]["value"].get<double>() == Approx(0.3 / 60.0).epsilon(0.04));
  // Read at 1 s, where white noise is all of sigma^2 and the EDF is that of white noise on
  // 4,000 samples: (3*4000/2 - 2*3999/4001) * 4/9 = 2665.8.
  CHECK(j["series"][0]["arw_deg_per_sqrt_h"]["from_tau_s"].get<double>() == 1.0);
  CHECK(j["series"][0]["arw_deg_per_sqrt_h"]["edf"].get<double>() == Approx(2665.8).epsilon(0.01));
  CHECK(j["series"][0]["arw_deg_per_sqrt_h"]["share"].get<double>() > 0.95);
  CHECK(j["series"][0]["fit"]["white_dph2_s"].get<double>() == Approx(0.09).epsilon(0.08));
  // sigma(1 s) of the curve is the noise's std itself.
  CHECK(j["series"][0]["curve"][0]["adev_dph"].get<double>() == Approx(0.3).epsilon(0.04));
  // White noise has no minimum within the record: said, not guessed.
  CHECK(j["series"][0]["bias_instability_dph"]["value"].is_null());
  CHECK(j["series"][0]["bias_instability_dph"]["note"].get<std::string>().find("no minimum") != std::string::npos);

  o.json = false;
  const auto table = allan(o);
  CHECK(table.out.find("hold 2") != std::string::npos);
  CHECK(table.out.find("ARW deg/sqrt(h)") != std::string::npos);
  CHECK(table.out.find("EDF") != std::string::npos);

  o.whole_run = true;
  o.json = true;
  const auto whole = nlohmann::json::parse(allan(o).out);
  REQUIRE(whole["series"].size() == 1);
  CHECK(whole["series"][0]["samples"] == 7000);
}

TEST_CASE("fogctl allan: bad input exits 2 naming what is wrong", "[cli][allan]") {
  Dir d;
  AllanOptions o;
  o.run = write_run(d.path, 0.3);
  o.min_samples = 3;
  auto r = allan(o);
  CHECK(r.code == kExitError);
  CHECK(r.err.find("--min-samples 3") != std::string::npos);

  o.min_samples = 5000;  // longer than either hold
  r = allan(o);
  CHECK(r.code == kExitError);
  CHECK(r.err.find("no stretch of 5000 or more") != std::string::npos);
  CHECK(r.err.find("--whole-run") != std::string::npos);

  o.min_samples = 600;
  o.model = (d.path / "missing-model.json").string();
  r = allan(o);
  CHECK(r.code == kExitError);
  CHECK(r.err.find("missing-model.json") != std::string::npos);
  CHECK(r.out.empty());

  o.model.clear();
  o.run = (d.path / "nope.csv").string();
  r = allan(o);
  CHECK(r.code == kExitError);
  CHECK(r.err.find("nope.csv") != std::string::npos);
}
