// The workbench on simulated runs with a hidden effect the paper's model lacks: compare shows
// the failure, diagnose ranks that effect first, adding it brings the compensated std back to
// the level of a run without it; with no hidden effect the model is adequate.
#include <catch2/catch.hpp>
#include <cmath>
#include <fstream>
#include <sstream>

#include "fogbench/model/model.hpp"
#include "fogbench/model/workbench.hpp"
#include "fogbench/profiles/profile.hpp"
#include "fogbench/sim/sim.hpp"
#include "programs.hpp"

using namespace fogbench;
namespace wb = model::workbench;

namespace {

using fogbench::test::program;

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

struct Runs {
  std::vector<model::RunData> all;  // exp1 (fit), exp2, exp3 (held out)
};
Runs runs(const std::string& effect, std::uint64_t seed) {
  return {{run("exp1", seed, effect), run("exp2", seed + 1, effect), run("exp3", seed + 2, effect)}};
}

double comp_std(const model::Model& m, const model::RunData& r) {
  auto v = model::verify(m, r);
  REQUIRE(v);
  return v->run.comp_std;
}

// The compensated std of the paper's model on runs without a hidden effect: sigma_a = 0.146
// deg/h of AR noise (k1 -0.005, k2 -0.04 add under 0.1%) plus a little misfit; measured
// 0.145 to 0.147 deg/h on exp1..3 over seeds 7, 21, 33 (docs/workbench.md). Ceilings below
// are in units of this level.
constexpr double kNoEffectDph = 0.147;

}  // namespace

TEST_CASE("workbench: with no hidden effect the paper's model is adequate") {
  const Runs r = runs("", 41);
  auto m = model::fit(r.all[0], *model::parse_terms("paper"));
  REQUIRE(m);
  for (const auto& x : r.all) {
    auto c = wb::compare(*m, x);
    REQUIRE(c);
    INFO(x.name);
    // A smoothed (61 s) residual of white noise has std 0.146/sqrt(61) = 0.019 deg/h: beyond
    // 3 sigma_a = 0.44 deg/h is 23 of its sigmas, so no interval may be reported.
    CHECK(c->failures.empty());
    CHECK(comp_std(*m, x) < 1.05 * kNoEffectDph);
  }
  auto d = wb::diagnose(*m, r.all[0], std::span<const model::RunData>(r.all).subspan(1));
  REQUIRE(d);
  INFO(d->summary);
  CHECK(d->adequate);
  REQUIRE(!d->candidates.empty());
  CHECK_FALSE(d->candidates.front().detected);
  // Every candidate was refitted or not refitted by its one-column update's fall (prune_fraction):
  // none was skipped for a missing signal (the simulator records the chamber air, so Ta and
  // d(Ta) are tried too).
  int evaluated = 0;
  for (const auto& c : d->candidates) evaluated += c.evaluated || c.skipped.starts_with("not refitted");
  CHECK(evaluated >= 12);
  // The paper's two betas are collinear on these profiles (grad = -core_tau dT1/dt on ramps).
  REQUIRE(d->collinear_coefs.size() == 1);
  CHECK(std::abs(d->collinear_coefs[0].r) > 0.9);
}

// Magnitudes found by trying (docs/workbench.md): each makes the paper model's compensated
// std on exp1 2.1 to 2.3 times its no-effect value (0.31 to 0.34 deg/h against 0.147).
TEST_CASE("workbench: a hidden effect is found, ranked first and removed by adding it") {
  struct Case {
    const char* effect;  // what the simulated gyro has beyond the paper's model
    const char* term;    // the library term diagnose must name first
  };
  const Case cases[] = {
      {"0.05*T1", "T1"},                 // absolute-temperature sensitivity, deg/h per degC
      {"0.007*T1^2", "T1^2"},            // quadratic sensitivity, deg/h per degC^2
      {"0.09*T1*d(T1)", "T1*d(T1)"},     // temperature-dependent Shupe coefficient
      {"-1.5*up(d(T1))", "up(d(T1))"},   // heating/cooling asymmetry, deg/h per degC/min
      {"0.05*lp(T1,300)", "lp(T1,300)"}, // a slow second thermal path
  };
  std::uint64_t seed = 100;
  for (const auto& cs : cases) {
    DYNAMIC_SECTION(cs.effect) {
      const Runs r = runs(cs.effect, seed);
      const std::span<const model::RunData> held = std::span<const model::RunData>(r.all).subspan(1);
      auto m = model::fit(r.all[0], *model::parse_terms("paper"));
      REQUIRE(m);
      // The failure shows: 1.5 to 3 times the no-effect level on the fit run, and compare
      // reports at least one failing interval on the fit run or a held-out one.
      const double before = comp_std(*m, r.all[0]);
      CHECK(before > 1.5 * kNoEffectDph);
      CHECK(before < 3.0 * kNoEffectDph);
      std::size_t failures = 0;
      for (const auto& x : r.all) {
        auto c = wb::compare(*m, x);
        REQUIRE(c);
        failures += c->failures.size();
      }
      CHECK(failures > 0);

      auto d = wb::diagnose(*m, r.all[0], held);
      REQUIRE(d);
      INFO(d->summary);
      CHECK_FALSE(d->adequate);
      REQUIRE(!d->candidates.empty());
      const auto& top = d->candidates.front();
      CHECK(top.expr == cs.term);
      CHECK(top.detected);
      CHECK(top.delta_bic < -100.0);
      CHECK(top.p_value < 1e-6);
      CHECK(top.held_out.size() == 2);
      // Look-alikes are named with what would separate them: on these profiles T1, T2, Ta and
      // lp(T1,300) correlate beyond 0.99 once the paper's terms are regressed out; up and down
      // of d(T1) are one effect when d(T1) is in the model.
      if (top.expr == "T1") {
        CHECK(!top.collinear_with.empty());
        CHECK(top.separate_by.find("separates T1 from") != std::string::npos);
      }
      if (top.expr == "up(d(T1))" && !top.collinear_with.empty()) CHECK(top.separate_by.find("written two ways") != std::string::npos);

      // Add it: back near the no-effect level on the fit run and on both held-out runs. The
      // refit has one more term, so "near" is within 5% (the lag and the coefficient are
      // estimated from one run: their error leaves a little misfit on the others).
      auto added = wb::add_term(*m, r.all[0], cs.term);
      REQUIRE(added);
      REQUIRE(added->model.parent);
      CHECK(added->model.note.find(cs.term) != std::string::npos);
      for (const auto& x : r.all) {
        INFO(x.name);
        const double after = comp_std(added->model, x);
        CHECK(after < 1.05 * kNoEffectDph);
        CHECK(after < comp_std(*m, x));
      }
      // The lineage shows the fall on every run.
      const auto l = wb::lineage(added->model, r.all);
      REQUIRE(l.steps.size() == 2);
      for (std::size_t i = 0; i < r.all.size(); ++i) CHECK(l.steps[1].comp_std_dph[i] < l.steps[0].comp_std_dph[i]);
    }
    seed += 10;
  }
}

TEST_CASE("workbench: a held-out run without the chamber's temperature skips Ta for that run and says so") {
  const Runs r = runs("0.05*T1", 200);
  auto m = model::fit(r.all[0], *model::parse_terms("paper"));
  REQUIRE(m);
  std::vector<model::RunData> held{r.all[1]};
  held[0].chamber_c.clear();  // recorded without the chamber's process value
  auto d = wb::diagnose(*m, r.all[0], held);
  REQUIRE(d);
  bool seen = false;
  for (const auto& c : d->candidates) {
    if (c.expr != "Ta" && c.expr != "d(Ta)") continue;
    REQUIRE(c.held_out.size() == 1);
    CHECK_FALSE(c.held_out[0].scored);
    CHECK(c.held_out[0].skipped.find("chamber_c") != std::string::npos);
    seen = true;
  }
  CHECK(seen);
  // The fit run itself without Ta: the candidate is skipped with the reason.
  model::RunData no_ta = r.all[0];
  no_ta.chamber_c.clear();
  auto d2 = wb::diagnose(*m, no_ta, {});
  REQUIRE(d2);
  for (const auto& c : d2->candidates)
    if (c.expr == "Ta") {
      CHECK_FALSE(c.evaluated);
      CHECK(c.skipped.find("Ta") != std::string::npos);
    }
  // Without held-out runs the stricter rule applies and still finds T1.
  CHECK(d2->rule.find("no held-out run") != std::string::npos);
  REQUIRE(!d2->candidates.empty());
  CHECK(d2->candidates.front().expr == "T1");
}

// TERMS.md's "a model term again at a second lag": the coil's rate acting again 300 s later (a
// second, slower thermal path). Its residual steps a lag after each ramp's corner, where the
// coil's rate is steady, which the bias-jump scan took for jumps (nine on three runs, removed
// from the data, so that no term could explain the rest); and the copy at a second lag was
// refitted beside the paper's lag frozen where the two paths had pulled it (12% off the
// residual). Now: no jump, the second path detected at its lag, and the search's model at the
// noise level on every run.
TEST_CASE("workbench: a second thermal path is found at its lag, its steps are not called bias jumps") {
  const Runs r = runs("-2*d(T1)@300", 51);
  auto m = model::fit(r.all[0], *model::parse_terms("paper"));
  REQUIRE(m);
  CHECK(comp_std(*m, r.all[0]) > 1.5 * kNoEffectDph);
  auto d = wb::diagnose(*m, r.all[0], std::span<const model::RunData>(r.all).subspan(1));
  REQUIRE(d);
  INFO(d->summary);
  CHECK(d->jumps.empty());
  CHECK_FALSE(d->adequate);
  bool second_path = false;
  for (const auto& c : d->candidates)
    if (c.second_lag && c.expr == "d(T1)" && c.detected) {
      INFO(c.term);
      CHECK(std::abs(c.lag_s - 300) <= 15);
      CHECK(c.term == "(d(T1)@" + std::to_string(c.lag_s) + ")");  // what add_term takes
      second_path = true;
    }
  CHECK(second_path);
  REQUIRE_FALSE(d->steps.empty());
  REQUIRE(d->final_checks.size() == 3);
  for (const auto& c : d->final_checks) {
    INFO(c.run);
    CHECK(c.comp_std_dph < 1.05 * kNoEffectDph);
  }
  // The second path as diagnose spells it, added by hand: the paper's lag refitted beside it.
  for (const auto& c : d->candidates)
    if (c.second_lag && c.expr == "d(T1)" && c.detected) {
      auto added = wb::add_term(*m, r.all[0], c.term);
      REQUIRE(added);
      for (const auto& x : r.all) {
        INFO(x.name);
        CHECK(comp_std(added->model, x) < 1.05 * kNoEffectDph);
      }
    }
}
