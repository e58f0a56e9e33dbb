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
#include "temp_dir.hpp"

using namespace fogbench;
using namespace fogbench::cli;
namespace fs = std::filesystem;

namespace {

using fogbench::cli::testing::Dir;

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

// Compiles a C file of the test's directory with fogcomp.h as strict C99, warnings as errors.
bool compile_c(const Dir& d, const std::string& source, const std::string& exe, const std::string& extra = "") {
  const std::string cc = std::getenv("CC") ? std::getenv("CC") : "cc";
  const std::string build = cc + " -std=c99 -pedantic -Wall -Wextra -Werror -O2" + extra + " -I" FOGBENCH_SOURCE_DIR "/firmware -I" +
                            d.path.string() + " " + d.file(source) + " -lm -o " + d.file(exe) + " 2> " + d.file("cc.log");
  const int built = std::system(build.c_str());
  std::ifstream log(d.file("cc.log"));
  INFO("C compiler: " << build << "\n" << std::string(std::istreambuf_iterator<char>(log), {}));
  CHECK(built == 0);  // no C compiler, or a warning in fogcomp.h or the generated model: a failure
  return built == 0;
}

// `fogctl coefficients model.json --format c --name unit_model -o model.inc --run run.csv
// --reference reference.csv` in `d` (after make_run_and_model).
CoefficientsOptions c_with_reference(const Dir& d) {
  CoefficientsOptions o;
  o.model = d.file("model.json");
  o.format = "c";
  o.name = "unit_model";
  o.output = d.file("model.inc");
  o.run = d.file("run.csv");
  o.reference = d.file("reference.csv");
  return o;
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
  CoefficientsOptions o = c_with_reference(d);
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
  REQUIRE(compile_c(d, "check.c", "check"));
  const std::string run = d.file("check") + " " + d.file("reference.csv") + " > " + d.file("check.out");
  const int ran = std::system(run.c_str());
  std::ifstream res(d.file("check.out"));
  INFO("C reference implementation: rows, largest difference (deg/h): " << std::string(std::istreambuf_iterator<char>(res), {}));
  CHECK(ran == 0);
}

TEST_CASE("firmware: a float build of fogcomp.h reproduces its own reference vector to its tolerance",
          "[cli][firmware]") {
  Dir d;
  make_run_and_model(d);
  CoefficientsOptions o = c_with_reference(d);
  o.single = true;
  REQUIRE(coefficients(o).code == kExitOk);
  o.single = false;
  o.reference = d.file("reference_double.csv");
  o.output = d.file("unused.inc");
  REQUIRE(coefficients(o).code == kExitOk);
  {
    // Read as doubles, computed in float: -Wdouble-promotion and -Wconversion catch any double
    // arithmetic left in the float build (a Cortex-M4F would do it in software).
    std::ofstream c(d.file("checkf.c"));
    c << R"(#define FOGCOMP_FLOAT
#include <stdio.h>
#include <math.h>
#include "fogcomp.h"
#include "model.inc"
static fogcomp_state st;
int main(int argc, char** argv) {
  FILE* f = fopen(argv[1], "r");
  FILE* g = fopen(argv[2], "r");
  char header[256];
  double t1, t2, ta, ton, gyro, mu, comp, mu_double, x, worst = 0.0, worst_double = 0.0;
  long rows = 0;
  (void)argc;
  if (!f || !g || !fgets(header, sizeof header, f) || !fgets(header, sizeof header, g) || fogcomp_check(&unit_model) != 0) return 3;
  fogcomp_init(&st);
  while (fscanf(f, "%lf,%lf,%lf,%lf,%lf,%lf,%lf", &t1, &t2, &ta, &ton, &gyro, &mu, &comp) == 7 &&
         fscanf(g, "%lf,%lf,%lf,%lf,%lf,%lf,%lf", &x, &x, &x, &x, &x, &mu_double, &x) == 7) {
    fogcomp_input in;
    double v;
    in.t1_c = (float)t1;
    in.t2_c = (float)t2;
    in.ta_c = (float)ta;
    in.ton_s = (float)ton;
    v = (double)fogcomp_step(&st, &unit_model, &in);
    if (fabs(v - mu) > worst) worst = fabs(v - mu);
    if (fabs(v - mu_double) > worst_double) worst_double = fabs(v - mu_double);
    ++rows;
  }
  printf("%ld %.3g %.3g\n", rows, worst, worst_double);
  return rows >= 1000 && worst <= 1e-4 && worst_double <= 1e-3 ? 0 : 1;
}
)";
  }
  REQUIRE(compile_c(d, "checkf.c", "checkf", " -Wconversion -Wdouble-promotion"));
  const std::string run = d.file("checkf") + " " + d.file("reference.csv") + " " + d.file("reference_double.csv") + " > " + d.file("check.out");
  const int ran = std::system(run.c_str());
  std::ifstream res(d.file("check.out"));
  INFO("float build: rows, largest difference from the float reference, from the double one (deg/h): "
       << std::string(std::istreambuf_iterator<char>(res), {}));
  CHECK(ran == 0);
}

TEST_CASE("firmware: fogcomp.h is clean whatever subset a file uses, and fogcomp_check refuses bad operations",
          "[cli][firmware]") {
  Dir d;
  {
    // Only fogcomp_init: no "defined but not used" for the other two (static inline).
    std::ofstream c(d.file("subset.c"));
    c << "#include \"fogcomp.h\"\nstatic fogcomp_state st;\nint main(void) {\n  fogcomp_init(&st);\n  return st.started;\n}\n";
  }
  CHECK(compile_c(d, "subset.c", "subset"));
  CHECK(compile_c(d, "subset.c", "subset_float", " -DFOGCOMP_FLOAT -Wconversion -Wdouble-promotion"));
  {
    // A well-formed model (T1 through lp, warm of ton), then one field broken at a time.
    std::ofstream c(d.file("bad.c"));
    c << R"(#include "fogcomp.h"
static fogcomp_model good(void) {
  fogcomp_model m;
  m.dt_s = 1.0; m.tref_c = 20.0; m.mu0_dph = 0.0; m.ring_size = 0; m.n_ops = 4; m.n_terms = 2;
  m.ops[0].kind = FOGCOMP_SIGNAL; m.ops[0].a = -1; m.ops[0].b = -1; m.ops[0].n = 0; m.ops[0].p = 0.0; m.ops[0].ring = -1;
  m.ops[1].kind = FOGCOMP_LP; m.ops[1].a = 0; m.ops[1].b = -1; m.ops[1].n = 0; m.ops[1].p = 0.01; m.ops[1].ring = -1;
  m.ops[2].kind = FOGCOMP_SIGNAL; m.ops[2].a = -1; m.ops[2].b = -1; m.ops[2].n = 3; m.ops[2].p = 0.0; m.ops[2].ring = -1;
  m.ops[3].kind = FOGCOMP_WARM; m.ops[3].a = 2; m.ops[3].b = -1; m.ops[3].n = 0; m.ops[3].p = 600.0; m.ops[3].ring = -1;
  m.term_op[0] = 1; m.term_op[1] = 3; m.beta[0] = 1.0; m.beta[1] = 1.0;
  return m;
}
int main(void) {
  fogcomp_model m = good();
  int bad = 0;
  if (fogcomp_check(&m) != 0) return 10;
  m = good(); m.ops[3].p = 0.0;          /* warm's time constant 0 s: exp(-t / 0) */
  bad += fogcomp_check(&m) != 0;
  m = good(); m.ops[1].p = 0.0;          /* lp's alpha 0: a filter that never moves (tau infinite) */
  bad += fogcomp_check(&m) != 0;
  m = good(); m.ops[1].kind = 42;        /* an unknown operation */
  bad += fogcomp_check(&m) != 0;
  m = good(); m.ops[1].kind = -1;
  bad += fogcomp_check(&m) != 0;
  m = good(); m.ops[0].n = 7;            /* no signal 7 */
  bad += fogcomp_check(&m) != 0;
  m = good(); m.ops[1].a = -1;           /* lp of nothing */
  bad += fogcomp_check(&m) != 0;
  m = good(); m.dt_s = 0.0;
  bad += fogcomp_check(&m) != 0;
  return bad == 7 ? 0 : 1;
}
)";
  }
  REQUIRE(compile_c(d, "bad.c", "bad"));
  CHECK(std::system(d.file("bad").c_str()) == 0);
}

TEST_CASE("fogctl coefficients: the README's offline sequence ends in a firmware form within 5 % of the model",
          "[cli][firmware]") {
  // fogctl simulate --profile exp1 --seed 1 (the distributed coil), fogctl fit: the paper's shared
  // lag lands at 0 s there; d(T1) is held at 30 s, its causal least, and the fit says so.
  Dir d;
  SimulateOptions s;
  s.profile = "exp1";
  s.seed = 1;
  s.output = d.file("exp1.csv");
  s.quiet = true;
  std::ostringstream o, e;
  REQUIRE(run_simulate(s, o, e) == kExitOk);
  FitCommandOptions f;
  f.run = d.file("exp1.csv");
  f.output = d.file("model.json");
  REQUIRE(run_fit(f, o, e) == kExitOk);
  CHECK(o.str().find("held for a causal firmware form") != std::string::npos);
  auto m = load_model(d.file("model.json"));
  REQUIRE(m);
  REQUIRE(m->terms.size() == 2);
  CHECK(m->terms[0].term.lag.seconds >= 30);  // d(T1)
  CHECK_FALSE(m->fit.lag_note.empty());

  CoefficientsOptions c;
  c.model = d.file("model.json");
  c.format = "c";
  c.output = d.file("model.inc");
  c.reference = d.file("ref.csv");
  auto r = coefficients(c);
  INFO(r.err);
  CHECK(r.code == kExitOk);
  c.format = "json";
  c.output = d.file("model_fw.json");
  r = coefficients(c);
  REQUIRE(r.code == kExitOk);
  const auto j = nlohmann::json::parse(std::ifstream(d.file("model_fw.json")));
  const double fw = j["reference"]["compensated_std_dph"], model = j["reference"]["model_compensated_std_dph"];
  CHECK(fw <= 1.05 * model);
  CHECK(fw >= 0.95 * model);

  // Fitted from lag 0 (--any-lag), the same run's model has no causal form: exit 2; --late
  // computes it 30 s late and exits 1, the cost beyond 5 %.
  f.any_lag = true;
  f.output = d.file("any.json");
  REQUIRE(run_fit(f, o, e) == kExitOk);
  c.model = d.file("any.json");
  c.output = d.file("any_fw.json");
  CHECK(coefficients(c).code == kExitError);
  c.late = true;
  r = coefficients(c);
  CHECK(r.code == kExitFailed);
  CHECK(r.err.find("NOT the model") != std::string::npos);
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

  // --late computes the whole model 17 s late instead (grad@13 too), says so and what it costs
  // on the reference run: exit 1 when that is more than 5 % of the compensated std.
  c.late = true;
  r = coefficients(c);
  CHECK((r.code == kExitOk || r.code == kExitFailed));
  CHECK(r.err.find("the model is computed 17 s later than it was fitted") != std::string::npos);
  const auto j = nlohmann::json::parse(std::ifstream(d.file("early.inc")));
  CHECK(j["terms"][0]["late_s"] == 17);
  CHECK(j["terms"][1]["late_s"] == 17);
  CHECK(j["reference"]["within_5_percent"] == (r.code == kExitOk));

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
