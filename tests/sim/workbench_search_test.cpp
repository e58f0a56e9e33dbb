// Issue 10: diagnose beyond the effects library, on simulated runs with hidden effects of every
// class (in the library, two at once, spellable but unlisted, a slow path at another time
// constant, a warm-up after power-on, a bias jump), each sized 1.3 to 2 times the noise floor
// on the fit run: the search names it (or a look-alike it names too), the error falls on the
// held-out runs, and `adequate` is false wherever something remains.
#include <catch2/catch.hpp>
#include <algorithm>
#include <cmath>

#include "fogbench/model/model.hpp"
#include "fogbench/model/workbench.hpp"
#include "fogbench/sim/sim.hpp"
#include "programs.hpp"

using namespace fogbench;
namespace wb = model::workbench;

namespace {

using fogbench::test::program;

// The lumped coil (the library's default): the paper's model is the exact truth without a
// hidden effect, so its compensated std is the noise floor, 0.147 deg/h (sigma_a 0.146 and
// AR(2) of -0.005, -0.04; docs/workbench.md measures 0.145 to 0.147 on exp1..3).
constexpr double kFloorDph = 0.147;

model::RunData run(const std::string& profile, std::uint64_t seed, const std::string& effect) {
  sim::SimConfig cfg;
  cfg.seed = seed;
  cfg.units[0].effects = effect;
  auto r = sim::simulate(cfg, program(profile));
  REQUIRE(r);
  model::RunData d = r->front();
  d.name = profile;
  return d;
}

std::vector<model::RunData> runs(const std::string& effect, std::uint64_t seed) {
  return {run("exp1", seed, effect), run("exp2", seed + 1, effect), run("exp3", seed + 2, effect)};
}

double comp_std(const model::Model& m, const model::RunData& r) {
  auto v = model::verify(m, r);
  REQUIRE(v);
  return v->run.comp_std;
}

struct Diag {
  model::Model m;
  wb::Diagnosis d;
};
Diag diagnose(const std::vector<model::RunData>& r, wb::DiagnoseOptions o = {}) {
  auto m = model::fit(r[0], *model::parse_terms("paper"));
  REQUIRE(m);
  auto d = wb::diagnose(*m, r[0], std::span<const model::RunData>(r).subspan(1), o);
  REQUIRE(d);
  return {*m, *d};
}

// The model with the steps of the search added, rebuilt with add_term from the printed terms
// (what a user does with `fit --add`), applied to every run.
model::Model with_steps(const Diag& x, const model::RunData& fit_run) {
  model::Model m = x.m;
  for (const auto& st : x.d.steps) {
    auto a = wb::add_term(m, fit_run, st.added);
    REQUIRE(a);
    m = a->model;
  }
  return m;
}

bool named(const wb::SearchStep& st, const std::string& expr) {
  return st.expr == expr || std::find(st.look_alikes.begin(), st.look_alikes.end(), expr) != st.look_alikes.end() ||
         std::any_of(st.look_alikes.begin(), st.look_alikes.end(), [&](const std::string& s) { return s.rfind(expr + "@", 0) == 0; });
}

// Adds a warm-up A*exp(-ton/tau) to the gyro, with the power-on `on_s` before the run's start
// recorded as the column since_power_on_s.
void add_warm_up(model::RunData& r, double a_dph, double tau_s, double on_s) {
  r.since_power_on_s.resize(r.size());
  for (std::size_t t = 0; t < r.size(); ++t) {
    r.since_power_on_s[t] = on_s + r.time_s[t];
    r.gyro_dph[t] += a_dph * std::exp(-r.since_power_on_s[t] / tau_s);
  }
}

}  // namespace

TEST_CASE("workbench search: with no hidden effect the model is adequate, with nothing found and no jump") {
  for (std::uint64_t seed : {300u, 310u}) {
    INFO("seed " << seed);
    const auto r = runs("", seed);
    const Diag x = diagnose(r);
    INFO(x.d.summary);
    CHECK(x.d.adequate);
    CHECK(x.d.reasons.empty());
    CHECK(x.d.steps.empty());
    CHECK(x.d.jumps.empty());
    CHECK_FALSE(x.d.outside_search);
    REQUIRE(x.d.checks.size() == 3);
    for (const auto& c : x.d.checks) {
      INFO(c.run);
      // 1.02 to 1.04 x the AR noise's std (docs/workbench.md): well inside 1.25.
      CHECK(c.noise_factor < 1.1);
      CHECK(c.failures.empty());
    }
    // The search space as documented: 12 time constants, 30 s to 4 h, under the limit.
    CHECK(x.d.search == "language");
    CHECK(x.d.search_space["tau_s"].size() == 12);
    CHECK(x.d.search_space["tau_s"].front() == 30);
    CHECK(x.d.search_space["tau_s"].back() == 14400);
    CHECK(x.d.search_space["total"].get<int>() <= 400);
  }
}

// Sizes found by trying: 1.3 to 2 x the floor on exp1 (the fit run), measured in the test.
TEST_CASE("workbench search: effects the language spells but the library does not list are found and removed") {
  // On these profiles T1, T2 and Ta at a lag are look-alikes (r > 0.99), so a cubic of T1 may
  // be named Ta^3@190 and T1*T2 as T2*Ta@94 or T1^2: what is checked is the family, which
  // the name or one of its named look-alikes must belong to.
  struct Case {
    const char* effect;
    std::vector<std::string> family;  // a substring of the name or of a look-alike
  };
  const Case cases[] = {
      {"0.0003*T1^3", {"^3"}},              // a cubic sensitivity, deg/h per degC^3
      {"0.004*T1*T2", {"*", "^2"}},         // a product of two signals, deg/h per degC^2
      {"0.08*lp(T1,1600)", {"lp("}},        // a slow path at 1600 s, not the library's 300 s
  };
  std::uint64_t seed = 400;
  for (const auto& cs : cases) {
    for (int k = 0; k < 2; ++k, seed += 10) {
      DYNAMIC_SECTION(cs.effect << " seed " << seed) {
        const auto r = runs(cs.effect, seed);
        const Diag x = diagnose(r);
        INFO(x.d.summary);
        const double before = comp_std(x.m, r[0]);
        CHECK(before > 1.3 * kFloorDph);
        CHECK(before < 2.0 * kFloorDph);
        CHECK_FALSE(x.d.adequate);
        REQUIRE(!x.d.steps.empty());
        const auto& st = x.d.steps.front();
        bool in_family = false;
        for (const auto& f : cs.family) {
          in_family = in_family || st.expr.find(f) != std::string::npos;
          for (const auto& l : st.look_alikes) in_family = in_family || l.find(f) != std::string::npos;
        }
        CHECK(in_family);
        // A look-alike the library lists keeps the library's name (T1*T2 may be named T1^2,
        // with T1*T2 among its look-alikes): st.library is not checked.
        // The error falls on every held-out run with the found terms, back near the floor.
        for (const auto& h : st.held_out) {
          INFO(h.run);
          CHECK(h.scored);
          CHECK(h.rms_after_dph < h.rms_before_dph);
        }
        const model::Model m2 = with_steps(x, r[0]);
        for (const auto& run : r) {
          INFO(run.name << " with " << m2.terms_string());
          CHECK(comp_std(m2, run) < 1.1 * kFloorDph);
        }
        // What the search leaves is checked the same way: outside_search exactly when the
        // final checks fail.
        bool final_ok = true;
        for (const auto& c : x.d.final_checks) final_ok = final_ok && c.reasons.empty();
        CHECK(x.d.outside_search == !final_ok);
      }
    }
  }
}

TEST_CASE("workbench search: two library effects at once are both named, in the library's words") {
  for (std::uint64_t seed : {500u, 510u}) {
    INFO("seed " << seed);
    const auto r = runs("0.03*T1 + 0.003*T1^2", seed);
    const Diag x = diagnose(r);
    INFO(x.d.summary);
    const double before = comp_std(x.m, r[0]);
    CHECK(before > 1.3 * kFloorDph);
    CHECK(before < 2.0 * kFloorDph);
    CHECK_FALSE(x.d.adequate);
    REQUIRE(x.d.steps.size() >= 2);
    bool t1 = false, t1sq = false;
    for (const auto& st : x.d.steps) {
      t1 = t1 || named(st, "T1");
      t1sq = t1sq || named(st, "T1^2");
    }
    CHECK(t1);
    CHECK(t1sq);
    const model::Model m2 = with_steps(x, r[0]);
    for (const auto& run : r) CHECK(comp_std(m2, run) < 1.1 * kFloorDph);
  }
}

// Not yet: with the paper's two-step method the warm-up is not found as warm(tau). Step 1
// takes mu0 from the opening hold, where the warm-up is largest, and step 2 regresses without
// an intercept, so a warm(tau) column raises BIC's fit but worsens the compensated std (0.221
// -> 0.276 deg/h for the true warm(900) on exp1). What is checked: the model is not called
// adequate, and diagnose says the residual follows the time since power-on.
TEST_CASE("workbench search: a warm-up after power-on makes the model not adequate and the residual follow ton") {
  for (std::uint64_t seed : {600u, 610u}) {
    INFO("seed " << seed);
    auto r = runs("", seed);
    // Power-on 300 s before each run; 1 deg/h decaying with 900 s (0.72 at t = 0).
    for (auto& x : r) add_warm_up(x, 1.0, 900.0, 300.0);
    const Diag x = diagnose(r);
    INFO(x.d.summary);
    const double before = comp_std(x.m, r[0]);
    CHECK(before > 1.3 * kFloorDph);
    CHECK(before < 2.0 * kFloorDph);
    CHECK_FALSE(x.d.adequate);
    CHECK_FALSE(x.d.reasons.empty());
    CHECK(x.d.search_space["ton"] == true);
    if (x.d.steps.empty()) {
      CHECK(x.d.outside_search);
      CHECK(x.d.residual_follows.find("ton") != std::string::npos);
    }

    // The same runs without the column: still not adequate, and no ton term is tried.
    auto r2 = r;
    for (auto& y : r2) y.since_power_on_s.clear();
    const Diag z = diagnose(r2);
    INFO(z.d.summary);
    CHECK_FALSE(z.d.adequate);
    CHECK(z.d.search_space["ton"] == false);
  }
}

TEST_CASE("workbench search: a bias jump is reported as not thermal, removed for that run only, never a term") {
  for (std::uint64_t seed : {700u, 710u}) {
    INFO("seed " << seed);
    auto r = runs("", seed);
    // +0.35 deg/h from 1800 s of exp1 (mid-way through the 20 min hold at 10 degC, far from
    // any ramp's corner): the step's variance 0.35^2 * 2/3 * 1/3 on top of the floor makes
    // sqrt(0.147^2 + 0.0272) = 0.221 deg/h, 1.5 x.
    for (std::size_t t = 1800; t < r[0].size(); ++t) r[0].gyro_dph[t] += 0.35;
    // -0.3 deg/h from 6000 s of exp3 (a held-out run), in its 20 min hold at 35 degC.
    for (std::size_t t = 6000; t < r[2].size(); ++t) r[2].gyro_dph[t] -= 0.3;
    const Diag x = diagnose(r);
    INFO(x.d.summary);
    CHECK_FALSE(x.d.adequate);
    REQUIRE(x.d.jumps.size() == 2);
    for (const auto& j : x.d.jumps) {
      INFO(j.message);
      const bool fit = j.run == "exp1";
      // The step's estimate: within 0.08 deg/h (about 3 standard errors of the scan's
      // estimate, 0.025 over +-300 s) and 30 s of where it was put.
      CHECK(std::abs(j.size_dph - (fit ? 0.35 : -0.3)) < 0.08);
      CHECK(std::abs(j.time_s - (fit ? 1800.0 : 6000.0)) < 30.0);
      CHECK(j.message.find("not a thermal effect") != std::string::npos);
    }
    // Nothing thermal is added for it, and with the jumps removed (on those runs only) the
    // model is the noise: nothing outside the search remains.
    for (const auto& st : x.d.steps) INFO("added " << st.added);
    CHECK(x.d.steps.empty());
    CHECK_FALSE(x.d.outside_search);
  }
}
