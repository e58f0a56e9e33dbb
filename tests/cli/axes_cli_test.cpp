// fogctl simulate --axes 3 and fit / verify / diagnose --axis on a three-axis unit's CSV: each
// axis its own model (recording its axis) and its own verdict, a y axis with a drift x does not
// have failing where x passes, and every bad axis named.
#include <catch2/catch.hpp>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "fogbench/storage/csv.hpp"
#include "offline.hpp"
#include "temp_dir.hpp"
#include "workbench.hpp"

using namespace fogbench::cli;

namespace {

using fogbench::cli::testing::Dir;

struct AxesOut {
  int code;
  std::string out, err;
};

template <class Opt, class Fn>
AxesOut axes_call(Fn fn, const Opt& o) {
  std::ostringstream out, err;
  const int c = fn(o, out, err);
  return {c, out.str(), err.str()};
}

SimulateOptions three_axis_sim(const std::string& profile, std::uint64_t seed, const std::string& path) {
  SimulateOptions o;
  o.profile = profile;
  o.seed = seed;
  o.output = path;
  o.coil = "lumped";  // the paper's model is x's exact truth: what y fails on is its own effect
  o.quiet = true;
  o.axes = 3;
  // y alone is 0.5 deg/h per degC more sensitive to the coil's temperature (as offline_test's
  // failing gyro, there on its one axis).
  o.axis_effects = {"y=0.5*T1"};
  return o;
}

nlohmann::json read_json(const std::string& path) {
  std::ifstream f(path);
  return nlohmann::json::parse(f);
}

// exp1 (fit) and exp3 (held out) of one three-axis unit, and each of x's and y's models.
struct AxesBench {
  Dir dir;
  std::string e1 = dir.file("e1.csv"), e3 = dir.file("e3.csv"), mx = dir.file("mx.json"), my = dir.file("my.json");
  AxesBench() {
    REQUIRE(axes_call(run_simulate, three_axis_sim("exp1", 3, e1)).code == kExitOk);
    REQUIRE(axes_call(run_simulate, three_axis_sim("exp3", 4, e3)).code == kExitOk);
    for (const auto& [axis, path] : {std::pair{"x", mx}, std::pair{"y", my}}) {
      FitCommandOptions f;
      f.run = e1;
      f.output = path;
      f.input.axis = axis;
      const AxesOut r = axes_call(run_fit, f);
      INFO(r.err);
      REQUIRE(r.code == kExitOk);
      CHECK_THAT(r.out, Catch::Contains(std::string("axis ") + axis));
    }
  }
};

}  // namespace

TEST_CASE("fogctl simulate --axes 3: y and z columns, the same housing, each axis its own noise and drift", "[axes]") {
  Dir d;
  const std::string path = d.file("u.csv");
  SimulateOptions o = three_axis_sim("exp1", 3, path);
  o.json = true;
  const AxesOut r = axes_call(run_simulate, o);
  REQUIRE(r.code == kExitOk);
  const auto summary = nlohmann::json::parse(r.out);
  CHECK(summary["axes"] == 3);
  CHECK(summary["axis_effects"]["y"] == "0.5*T1");
  CHECK(summary["axis_effects"]["x"] == "");
  auto run = fogbench::storage::read_csv_file(path);
  REQUIRE(run);
  REQUIRE(run->has_axes());
  const std::size_t n = run->size();
  REQUIRE(n > 1000);
  // y - x is 0.5 x (T1_true - 20 degC) plus two axes' independent noise; z - x the noise alone.
  // exp1 moves T1 by several degC, so y - x spans degrees of deg/h where z - x stays near 0.
  double y_lo = 1e9, y_hi = -1e9, z_sum2 = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    y_lo = std::min(y_lo, run->gyro_y_dph[i] - run->gyro_dph[i]);
    y_hi = std::max(y_hi, run->gyro_y_dph[i] - run->gyro_dph[i]);
    const double dz = run->gyro_z_dph[i] - run->gyro_dph[i];
    z_sum2 += dz * dz;
  }
  CHECK(y_hi - y_lo > 2.0);
  // Two independent AR(2) noises of sigma_a 0.146 deg/h and rare 2.5 deg/h spikes: rms of the
  // difference about 0.21 deg/h, well under 0.5.
  CHECK(std::sqrt(z_sum2 / static_cast<double>(n)) < 0.5);
  CHECK(std::sqrt(z_sum2 / static_cast<double>(n)) > 0.1);  // z is not a copy of x

  // Bad axis options: named, exit 2, nothing written.
  SimulateOptions bad = three_axis_sim("exp1", 3, d.file("bad.csv"));
  bad.axis_effects = {"w=0.1*T1"};
  AxesOut b = axes_call(run_simulate, bad);
  CHECK(b.code == kExitError);
  CHECK_THAT(b.err, Catch::Contains("--axis-effect w=0.1*T1") && Catch::Contains("AXIS x, y or z"));
  bad.axis_effects = {"y=0.1*T9"};
  b = axes_call(run_simulate, bad);
  CHECK(b.code == kExitError);
  CHECK_THAT(b.err, Catch::Contains("--axis-effect y=0.1*T9"));
  // Read by the simulator's own rule (sim::parse_axis_effects, fogbench-sim's too): a lag the
  // simulator cannot draw is refused here, before any sample is made.
  bad.axis_effects = {"z=0.1*T1@auto"};
  b = axes_call(run_simulate, bad);
  CHECK(b.code == kExitError);
  CHECK_THAT(b.err, Catch::Contains("--axis-effect z=0.1*T1@auto") && Catch::Contains("fixed lag"));
  bad.axis_effects = {"y=0.1*T1"};
  bad.axes = 1;
  b = axes_call(run_simulate, bad);
  CHECK(b.code == kExitError);
  CHECK_THAT(b.err, Catch::Contains("--axis-effect needs --axes 3"));
  CHECK_FALSE(std::filesystem::exists(d.file("bad.csv")));
}

TEST_CASE("fogctl fit and verify --axis: each axis its model and verdict, y's own drift fails y alone", "[axes]") {
  AxesBench b;
  CHECK(read_json(b.mx)["axis"] == "x");
  CHECK(read_json(b.my)["axis"] == "y");
  CHECK(read_json(b.mx)["fitted_on"]["fingerprint"] != read_json(b.my)["fitted_on"]["fingerprint"]);

  // Each model verifies its own axis (the model's axis when --axis is not given).
  VerifyOptions v;
  v.model = b.mx;
  v.runs = {b.e3};
  v.json = true;
  const AxesOut vx = axes_call(run_verify, v);
  INFO(vx.err);
  CHECK(vx.code == kExitOk);
  CHECK(nlohmann::json::parse(vx.out)["pass"] == true);
  v.model = b.my;
  const AxesOut vy = axes_call(run_verify, v);
  INFO(vy.err);
  CHECK(vy.code == kExitFailed);
  CHECK(nlohmann::json::parse(vy.out)["verdict"] == "fail");
  v.json = false;
  const AxesOut vt = axes_call(run_verify, v);
  CHECK_THAT(vt.out, Catch::Contains("axis y") && Catch::Contains("FAIL"));

  // compare follows the model's axis too (it has no --axis): y's model on y's output, where
  // its failing intervals are.
  CompareCommandOptions c;
  c.model = b.my;
  c.runs = {b.e3};
  c.json = true;
  const AxesOut cy = axes_call(run_compare, c);
  INFO(cy.err);
  CHECK(cy.code == kExitFailed);
  CHECK(cy.err.find("axis") == std::string::npos);

  // Another axis than the model's: refused, naming both.
  v.input.axis = "x";
  const AxesOut wrong = axes_call(run_verify, v);
  CHECK(wrong.code == kExitError);
  CHECK_THAT(wrong.err, Catch::Contains("fitted on axis y") && Catch::Contains("holds axis x"));
}

TEST_CASE("fogctl fit --axis: recovers the axis's own coefficient, refuses y or z of a one-axis CSV", "[axes]") {
  AxesBench b;
  // y's T1 sensitivity is 0.5 deg/h per degC, x's 0: a joint fit of the truth's terms plus T1
  // on each axis of exp1 (lumped coil: those terms are the exact truth). T1 spans several degC
  // over exp1 in 0.146 deg/h noise, so its coefficient is determined to about 1e-3
  // (measured: off by 3e-4 on x, 9e-5 on y); 0.01 is 2 % of y's.
  for (const auto& [axis, truth] : {std::pair{"x", 0.0}, std::pair{"y", 0.5}}) {
    FitCommandOptions f;
    f.run = b.e1;
    f.terms = "d(T1)@38 + grad@38 + T1";
    f.json = true;
    f.input.axis = axis;
    const AxesOut r = axes_call(run_fit, f);
    INFO(axis << ": " << r.err);
    REQUIRE(r.code == kExitOk);
    const auto j = nlohmann::json::parse(r.out);
    CHECK(j["axis"] == axis);
    CHECK(j["terms"][2]["coef"].get<double>() == Approx(truth).margin(0.01));
  }

  Dir d;
  std::ofstream(d.file("one.csv")) << "time_s,gyro_dph,t1_c,t2_c\n0,1,20,20\n1,1,20,20\n";
  FitCommandOptions f;
  f.run = d.file("one.csv");
  f.input.axis = "z";
  const AxesOut r = axes_call(run_fit, f);
  CHECK(r.code == kExitError);
  CHECK_THAT(r.err, Catch::Contains("one.csv") && Catch::Contains("axis z") && Catch::Contains("one-axis"));
  f.input.axis = "q";
  const AxesOut q = axes_call(run_fit, f);
  CHECK(q.code == kExitError);
  CHECK_THAT(q.err, Catch::Contains("--axis q: expected x, y or z"));
}

TEST_CASE("fogctl diagnose --axis: y's missing effect is found on y, from y's model", "[axes]") {
  AxesBench b;
  DiagnoseCommandOptions d;
  d.model = b.my;  // its axis, y, is the runs' axis read
  d.runs = {b.e1, b.e3};
  d.json = true;
  d.search = "library";
  const AxesOut r = axes_call(run_diagnose, d);
  INFO(r.err);
  CHECK(r.code == kExitFailed);
  const auto j = nlohmann::json::parse(r.out);
  CHECK(j["adequate"] == false);
  CHECK(j["candidates"][0]["expr"] == "T1");
}

namespace {

// exp1 and exp3 of a three-axis unit whose axes have their own coil thermistors, x with a
// cross-axis drift: 0.3 deg/h per degC of axis y's coil centre (lumped coil: the paper's terms
// are x's exact truth besides).
struct CrossBench {
  Dir dir;
  std::string e1 = dir.file("c1.csv"), e3 = dir.file("c3.csv"), mx = dir.file("cx.json");
  static SimulateOptions sim(const std::string& profile, std::uint64_t seed, const std::string& path) {
    SimulateOptions o = three_axis_sim(profile, seed, path);
    o.axis_thermistors = true;
    o.axis_effects = {"x=0.3*T1y"};
    return o;
  }
  CrossBench() {
    const AxesOut s1 = axes_call(run_simulate, sim("exp1", 5, e1));
    INFO(s1.err);
    REQUIRE(s1.code == kExitOk);
    REQUIRE(axes_call(run_simulate, sim("exp3", 6, e3)).code == kExitOk);
    FitCommandOptions f;
    f.run = e1;
    f.output = mx;
    f.input.axis = "x";
    REQUIRE(axes_call(run_fit, f).code == kExitOk);
  }
};

}  // namespace

TEST_CASE("fogctl simulate --axis-thermistors: each axis its own coil thermistors, written and read back", "[axes][cross_axis]") {
  CrossBench b;
  auto run = fogbench::storage::read_csv_file(b.e1);
  REQUIRE(run);
  REQUIRE(run->has_axes());
  REQUIRE(run->has_axis_thermistors());
  // x's are the file's t1_c, t2_c; y's and z's coils sit deeper in the housing, so on the ramps
  // they lag x's (by degC), z's more than y's, and all start together.
  CHECK(run->axis_t1_c[0] == run->t1_c);
  CHECK(run->axis_t2_c[0] == run->t2_c);
  double y_apart = 0.0, z_apart = 0.0;
  for (std::size_t i = 0; i < run->size(); ++i) {
    y_apart = std::max(y_apart, std::abs(run->axis_t1_c[1][i] - run->t1_c[i]));
    z_apart = std::max(z_apart, std::abs(run->axis_t1_c[2][i] - run->t1_c[i]));
  }
  CHECK(y_apart > 0.3);
  CHECK(z_apart > y_apart);
  CHECK(std::abs(run->axis_t1_c[1][0] - run->t1_c[0]) < 0.1);
  // Written as read: the four columns come back the same.
  const auto again = fogbench::storage::parse_csv(fogbench::storage::to_csv(*run), fogbench::storage::CsvOptions{});
  REQUIRE(again);
  CHECK(again->axis_t1_c == run->axis_t1_c);
  CHECK(again->axis_t2_c == run->axis_t2_c);
  // Picked as y, the run's T1, T2 are y's own and the others' stay for the cross-axis signals.
  auto y = fogbench::model::select_axis(*run, fogbench::model::Axis::y);
  REQUIRE(y);
  CHECK(y->t1_c == run->axis_t1_c[1]);
  CHECK(y->axis_t1_c == run->axis_t1_c);

  // Refused: the flag without three axes, a cross-axis term without it.
  SimulateOptions one = CrossBench::sim("exp1", 5, b.dir.file("bad.csv"));
  one.axes = 1;
  one.axis_effects.clear();
  AxesOut r = axes_call(run_simulate, one);
  CHECK(r.code == kExitError);
  CHECK_THAT(r.err, Catch::Contains("--axis-thermistors needs --axes 3"));
  SimulateOptions shared = CrossBench::sim("exp1", 5, b.dir.file("bad.csv"));
  shared.axis_thermistors = false;
  r = axes_call(run_simulate, shared);
  CHECK(r.code == kExitError);
  CHECK_THAT(r.err, Catch::Contains("--axis-effect x=0.3*T1y") && Catch::Contains("own coil thermistor"));
  CHECK_FALSE(std::filesystem::exists(b.dir.file("bad.csv")));
}

TEST_CASE("fogctl simulate --axis-thermistors: a cross-axis term adds its coefficient times the other coil at its lag", "[axes][cross_axis]") {
  Dir dir;
  const std::string with_path = dir.file("with.csv"), without_path = dir.file("without.csv");
  SimulateOptions with = CrossBench::sim("exp1", 7, with_path);
  with.axis_effects = {"x=0.3*T1y@20"};
  SimulateOptions without = with;
  without.output = without_path;
  without.axis_effects.clear();
  REQUIRE(axes_call(run_simulate, with).code == kExitOk);
  REQUIRE(axes_call(run_simulate, without).code == kExitOk);
  auto a = fogbench::storage::read_csv_file(with_path);
  auto b = fogbench::storage::read_csv_file(without_path);
  REQUIRE(a);
  REQUIRE(b);
  REQUIRE(a->size() == b->size());
  // The same seed: the same coils, thermistors and noise; only x's output differs, by
  // 0.3 deg/h per degC of y's recorded coil centre (above Tref 20 degC) 20 s earlier (the first
  // sample before the run's start). The CSV's numbers read back exactly (shortest round trip),
  // so the margin is the rounding of one addition at ~10 deg/h.
  CHECK(a->axis_t1_c == b->axis_t1_c);
  CHECK(a->gyro_y_dph == b->gyro_y_dph);
  CHECK(a->gyro_z_dph == b->gyro_z_dph);
  double largest = 0.0;
  for (std::size_t i = 0; i < a->size(); ++i) {
    const double want = 0.3 * (a->axis_t1_c[1][i >= 20 ? i - 20 : 0] - 20.0);
    INFO("sample " << i);
    REQUIRE(a->gyro_dph[i] - b->gyro_dph[i] == Approx(want).margin(1e-9));
    largest = std::max(largest, std::abs(want));
  }
  CHECK(largest > 1.0);  // exp1 takes the coil well away from Tref: the comparison is not of zeros
}

TEST_CASE("fogctl fit --axis x: a cross-axis term's coefficient recovered, refused on shared thermistors", "[axes][cross_axis]") {
  CrossBench b;
  FitCommandOptions f;
  f.run = b.e1;
  f.terms = "d(T1)@38 + grad@38 + T1y";
  f.json = true;
  f.input.axis = "x";
  const AxesOut r = axes_call(run_fit, f);
  INFO(r.err);
  REQUIRE(r.code == kExitOk);
  const auto j = nlohmann::json::parse(r.out);
  CHECK(j["terms"][2]["term"].get<std::string>().find("T1y") != std::string::npos);
  CHECK(j["terms"][2]["coef"].get<double>() == Approx(0.3).margin(0.02));

  // The same term on a unit whose axes share their thermistors: named, exit 2.
  AxesBench shared;
  f.run = shared.e1;
  const AxesOut s = axes_call(run_fit, f);
  CHECK(s.code == kExitError);
  CHECK_THAT(s.err, Catch::Contains("T1y") && Catch::Contains("t1_y_c"));
}

TEST_CASE("fogctl diagnose --axis x: the cross-axis coupling is found and named", "[axes][cross_axis]") {
  CrossBench b;
  DiagnoseCommandOptions d;
  d.model = b.mx;
  d.runs = {b.e1, b.e3};
  d.json = true;
  d.search = "library";
  const AxesOut r = axes_call(run_diagnose, d);
  INFO(r.err << r.out.substr(0, 3000));
  CHECK(r.code == kExitFailed);
  const auto j = nlohmann::json::parse(r.out);
  CHECK(j["adequate"] == false);
  // The first step is y's coil (or a term the runs cannot tell from it, with T1y named beside).
  REQUIRE_FALSE(j["steps"].empty());
  const auto& first = j["steps"][0];
  bool named = first["expr"] == "T1y";
  for (const auto& la : first.value("look_alikes", nlohmann::json::array())) named = named || la == "T1y";
  CHECK(named);
}
