// fogctl coefficients and the firmware form of a model: the causal program computes what the
// fit's predict() does (once its windows are full), the C99 reference implementation compiled
// by the system's C compiler reproduces fogctl's reference vector, and what firmware cannot
// compute is refused naming the term.
#include <catch2/catch.hpp>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "coefficients.hpp"
#include "fogbench/model/firmware.hpp"
#include "offline.hpp"

using namespace fogbench;
using namespace fogbench::cli;
namespace fs = std::filesystem;

namespace {

struct Dir {
  fs::path path = fs::temp_directory_path() / ("fogctl-coef-" + std::to_string(::getpid()));
  Dir() { fs::create_directories(path); }
  ~Dir() { fs::remove_all(path); }
  std::string file(const std::string& n) const { return (path / n).string(); }
};

struct Result {
  int code;
  std::string out, err;
};

Result coefficients(const CoefficientsOptions& o) {
  std::ostringstream out, err;
  const int c = run_coefficients(o, out, err);
  return {c, out.str(), err.str()};
}

// A lumped-coil exp1 run and a model with every kind of delay: a lagged slope, a lagged plain
// signal, a filter from the start, a product of a signal and a slope.
constexpr const char* kTerms = "d(T1)@40 + grad@40 + lp(T1,600) + T1*d(T1)@35";

void make_run_and_model(const Dir& d) {
  SimulateOptions s;
  s.profile = "exp1";
  s.output = d.file("run.csv");
  s.coil = "lumped";
  s.quiet = true;
  std::ostringstream o, e;
  REQUIRE(run_simulate(s, o, e) == kExitOk);
  FitCommandOptions f;
  f.run = d.file("run.csv");
  f.terms = kTerms;
  f.output = d.file("model.json");
  REQUIRE(run_fit(f, o, e) == kExitOk);
}

}  // namespace

TEST_CASE("firmware: the causal program computes the model's prediction once its windows are full",
          "[cli][firmware]") {
  Dir d;
  make_run_and_model(d);
  auto m = load_model(d.file("model.json"));
  REQUIRE(m);
  auto run = load_run(d.file("run.csv"), {});
  REQUIRE(run);
  auto p = model::firmware::compile(*m);
  REQUIRE(p);
  for (const auto& t : p->terms) CHECK(t.late_s == 0);
  // History: d(T1)@40 is a 61-sample window delayed 10; T1*d(T1)@35 waits 30 samples for T1
  // and 5 more; grad@40 a 40-sample delay: 61 + 10 + 61 + 30 + 5 + 40 = 207 samples.
  CHECK(p->ring_size == 207);
  auto mu = model::predict(*m, *run);
  REQUIRE(mu);
  model::firmware::Compensator c(*p);
  double worst_dph = 0.0;
  // From sample 70 on, every slope the fit centres on sample i - lag has its 61 samples in the
  // run, and the causal window that ends 30 samples later is full of real samples too; before
  // that the firmware's windows hold the first sample (the opening hold): not compared.
  for (std::size_t i = 0; i < run->size(); ++i) {
    const double v = c.step({run->t1_c[i], run->t2_c[i], 0.0, 0.0});
    if (i >= 70) worst_dph = std::max(worst_dph, std::abs(v - (*mu)[i]));
  }
  INFO("largest difference from predict(): " << worst_dph << " deg/h");
  CHECK(worst_dph < 1e-9);
}

TEST_CASE("firmware: the C99 reference implementation reproduces fogctl's reference vector",
          "[cli][firmware]") {
  Dir d;
  make_run_and_model(d);
  CoefficientsOptions o;
  o.model = d.file("model.json");
  o.format = "c";
  o.name = "unit_model";
  o.output = d.file("model.inc");
  o.run = d.file("run.csv");
  o.reference = d.file("reference.csv");
  const auto r = coefficients(o);
  REQUIRE(r.code == kExitOk);
  {
    std::ofstream c(d.file("check.c"));
    c << R"(#include <stdio.h>
#include <math.h>
#include "fogcomp.h"
#include "model.inc"
static fogcomp_state st; /* static: the state is large for a stack */
int main(int argc, char** argv) {
  FILE* f = fopen(argv[1], "r");
  char header[256];
  fogcomp_input in;
  double gyro, mu, comp, worst = 0.0;
  long rows = 0;
  (void)argc;
  if (!f || !fgets(header, sizeof header, f) || fogcomp_check(&unit_model) != 0) return 3;
  fogcomp_init(&st);
  while (fscanf(f, "%lf,%lf,%lf,%lf,%lf,%lf,%lf", &in.t1_c, &in.t2_c, &in.ta_c, &in.ton_s, &gyro, &mu, &comp) == 7) {
    const double v = fogcomp_step(&st, &unit_model, &in);
    if (fabs(v - mu) > worst) worst = fabs(v - mu);
    if (fabs((gyro - v) - comp) > worst) worst = fabs((gyro - v) - comp);
    ++rows;
  }
  printf("%ld %.3g\n", rows, worst);
  return rows >= 1000 && worst <= 1e-9 ? 0 : 1;
}
)";
  }
  const std::string cc = std::getenv("CC") ? std::getenv("CC") : "cc";
  const std::string build = cc + " -std=c99 -pedantic -Wall -Wextra -Werror -O2 -I" FOGBENCH_SOURCE_DIR "/firmware -I" +
                            d.path.string() + " " + d.file("check.c") + " -lm -o " + d.file("check") + " 2> " + d.file("cc.log");
  const int built = std::system(build.c_str());
  std::ifstream log(d.file("cc.log"));
  INFO("C compiler: " << build << "\n" << std::string(std::istreambuf_iterator<char>(log), {}));
  REQUIRE(built == 0);  // no C compiler, or a warning in fogcomp.h or the generated model: a failure
  const std::string run = d.file("check") + " " + d.file("reference.csv") + " > " + d.file("check.out");
  const int ran = std::system(run.c_str());
  std::ifstream res(d.file("check.out"));
  INFO("C reference implementation: rows, largest difference (deg/h): " << std::string(std::istreambuf_iterator<char>(res), {}));
  CHECK(ran == 0);
}

TEST_CASE("fogctl coefficients: what firmware cannot compute, and bad options, exit 2 naming why",
          "[cli][firmware]") {
  Dir d;
  make_run_and_model(d);
  // Refit with a lag under the slope's half-window: the centred slope ends 17 s in the future.
  FitCommandOptions f;
  f.run = d.file("run.csv");
  f.terms = "d(T1)@13 + grad@13";
  f.output = d.file("early.json");
  std::ostringstream o, e;
  REQUIRE(run_fit(f, o, e) == kExitOk);

  CoefficientsOptions c;
  c.model = d.file("early.json");
  c.run = d.file("run.csv");
  c.output = d.file("early.inc");
  auto r = coefficients(c);
  CHECK(r.code == kExitError);
  CHECK(r.err.find("term d(T1)@13 cannot be computed by firmware") != std::string::npos);
  CHECK(r.err.find("17 s ahead") != std::string::npos);
  CHECK(r.err.find("--late") != std::string::npos);
  CHECK_FALSE(fs::exists(d.file("early.inc")));

  // --late computes it 17 s late instead, and says so.
  c.late = true;
  r = coefficients(c);
  CHECK(r.code == kExitOk);
  CHECK(r.err.find("d(T1)@13 is computed 17 s later than the model") != std::string::npos);
  const auto j = nlohmann::json::parse(std::ifstream(d.file("early.inc")));
  CHECK(j["terms"][0]["late_s"] == 17);
  CHECK(j["terms"][1]["late_s"] == 0);

  c = {};
  c.model = d.file("model.json");
  c.run = d.file("run.csv");
  c.format = "xml";
  r = coefficients(c);
  CHECK(r.code == kExitError);
  CHECK(r.err.find("--format xml") != std::string::npos);
  c.format = "c";
  c.name = "2bad name";
  r = coefficients(c);
  CHECK(r.code == kExitError);
  CHECK(r.err.find("not a C identifier") != std::string::npos);
}
