// The workbench on gyros with the noise real FOGs have (flicker, rate random walk) and no
// thermal effect beyond the paper's model: the paper's model must be called adequate and
// verify must pass, since the yardstick is the gyro's own noise read off its holds, not AR(2)
// whiteness; and a hidden effect well above that noise must still be found.
#include <catch2/catch.hpp>
#include <cmath>
#include <cstdlib>
#include <iostream>

#include "fogbench/model/model.hpp"
#include "fogbench/model/workbench.hpp"
#include "fogbench/sim/sim.hpp"
#include "programs.hpp"

using namespace fogbench;
namespace wb = model::workbench;

namespace {

using fogbench::test::program;

struct Noise {
  double arw_deg_per_sqrt_h, bias_instability_dph, rrw_dph_per_sqrt_h;
};

model::RunData run(const std::string& profile, std::uint64_t seed, const Noise& nz, const std::string& effect) {
  sim::SimConfig cfg;
  cfg.seed = seed;
  auto& u = cfg.units[0];
  u.coil.model = sim::CoilModel::lumped;  // the paper's model is the exact truth
  u.effects = effect;
  u.gyro.sigma_a_dph = 60.0 * nz.arw_deg_per_sqrt_h;  // ARW N deg/sqrt(h): 60 N deg/h a second
  u.gyro.bias_instability_dph = nz.bias_instability_dph;
  u.gyro.rrw_dph_per_sqrt_h = nz.rrw_dph_per_sqrt_h;
  auto r = sim::simulate(cfg, program(profile));
  REQUIRE(r);
  model::RunData d = r->front();
  d.name = profile;
  return d;
}

}  // namespace

TEST_CASE("workbench: real FOG noise with no thermal effect raises no alarm", "[noise]") {
  // The corners of the range: ARW 0.001 to 0.01 deg/sqrt(h), bias instability up to
  // 0.05 deg/h, rate random walk up to 0.1 deg/h/sqrt(h). Under AR(2) whiteness alone 2 to 9 of
  // 10 seeds were NOT ADEQUATE; the goal is at most 5 %: here at most 1 alarm in 15 diagnoses
  // (and as many verifies of 3 runs each).
  const Noise cases[] = {{0.001, 0.0, 0.1}, {0.001, 0.05, 0.0}, {0.01, 0.05, 0.1}};
  int alarms = 0, verdicts = 0, diagnoses = 0;
  std::string why;  // each alarm's case and reasons, shown when the count fails
  std::uint64_t seed = 500;
  for (const auto& nz : cases) {
    for (int k = 0; k < 5; ++k, seed += 10) {
      const std::vector<model::RunData> r = {run("exp1", seed, nz, ""), run("exp2", seed + 1, nz, ""), run("exp3", seed + 2, nz, "")};
      auto m = model::fit(r[0], *model::parse_terms("paper"));
      REQUIRE(m);
      auto d = wb::diagnose(*m, r[0], std::span<const model::RunData>(r).subspan(1));
      REQUIRE(d);
      ++diagnoses;
      INFO("ARW " << nz.arw_deg_per_sqrt_h << " B " << nz.bias_instability_dph << " RRW " << nz.rrw_dph_per_sqrt_h << " seed " << seed);
      INFO(d->summary);
      for (const auto& c : d->checks) INFO(c.run << ": " << c.floor_note);
      if (!d->adequate) {
        ++alarms;
        why += "ARW " + std::to_string(nz.arw_deg_per_sqrt_h) + " B " + std::to_string(nz.bias_instability_dph) + " RRW " +
               std::to_string(nz.rrw_dph_per_sqrt_h) + " seed " + std::to_string(seed) + ":";
        for (const auto& x : d->reasons) why += " [" + x + "]";
        for (const auto& c : d->checks) why += " {" + c.run + ": " + c.floor_note + "}";
        why += "\n";
      }
      // verify's second test (the same rule): the paper's ratio rule is not asked here, since at
      // ARW 0.01 deg/sqrt(h) (0.6 deg/h a second) the noise alone is 33-46 % of the raw std,
      // a true fail of the paper's rule, not an alarm.
      for (const auto& x : r) {
        auto v = model::verify(*m, x);
        REQUIRE(v);
        if (v->noise_factor > v->noise_limit_factor || v->longest_fail_s >= 60.0) ++verdicts;
      }
    }
  }
  CHECK(diagnoses == 15);
  INFO(why);
  CHECK(alarms <= 1);
  CHECK(verdicts <= 2);
}

TEST_CASE("workbench: flicker with a rate random walk the holds cannot see raises no alarm", "[noise]") {
  // The corner the holds are blind to (docs/workbench.md "Real FOG noise: where the floor is
  // blind"): ARW 0.001 deg/sqrt(h), bias instability 0.05 deg/h and rate random walk 0.1
  // deg/h/sqrt(h) at once. The holds' clusters end near 181 s, where the walk is under the
  // flicker: the floor sees flicker only, and the walk's K sqrt(T/6) = 0.044-0.066 deg/h over a
  // run made 11 of 21 seeds NOT ADEQUATE before the rule allowed for the walk the holds cannot
  // exclude. The seeds are fogctl simulate's (--seed 10 s + N for expN), s = 405..424.
  const Noise nz{0.001, 0.05, 0.1};
  int alarms = 0, diagnoses = 0;
  std::string why;
  for (std::uint64_t s = 405; s <= 424; ++s) {
    const std::vector<model::RunData> r = {run("exp1", 10 * s + 1, nz, ""), run("exp2", 10 * s + 2, nz, ""), run("exp3", 10 * s + 3, nz, "")};
    auto m = model::fit(r[0], *model::parse_terms("paper"));
    REQUIRE(m);
    auto d = wb::diagnose(*m, r[0], std::span<const model::RunData>(r).subspan(1));
    REQUIRE(d);
    ++diagnoses;
    // The floor says what it cannot exclude, wherever it allowed for it.
    for (const auto& c : d->checks) {
      INFO(c.floor_note);
      if (c.noise_limit_factor > 1.25 + 1e-9 && c.floor_note.find("bias instability") != std::string::npos)
        CHECK(c.floor_note.find("rate random walk") != std::string::npos);
    }
    if (!d->adequate) {
      ++alarms;
      why += "seed " + std::to_string(s) + ":";
      for (const auto& x : d->reasons) why += " [" + x + "]";
      why += "\n";
    }
  }
  CHECK(diagnoses == 20);
  INFO(why);
  CHECK(alarms <= 1);  // the goal: at most 5 %
}

TEST_CASE("workbench: a rate random walk the holds cannot see does not fail the whiteness test", "[noise]") {
  // ARW 0.001 deg/sqrt(h) (0.06 deg/h a second) with a rate random walk of 0.05 deg/h/sqrt(h)
  // and no flicker: the holds' clusters (up to 181 s) see white noise alone, so no slow noise is
  // allowed for, while over a 2.6 h run the walk is up to 0.4 of the residual's variance and
  // lifted every short lag of the ACF alike (RMS 0.34-0.42 on the worst runs against 0.05
  // allowed): 3 of these 20 seeds NOT ADEQUATE for whiteness alone on the unfiltered
  // statistic (705, 717; and 709, where the search also takes a walk for a slow path). The
  // statistic is now taken on the residual less its 301 s average (model.hpp's
  // kWhitenessHighpassS). The seeds are fogctl simulate's (--seed 10 s + N for expN),
  // docs/workbench.md "Slow noise and the whiteness statistic".
  const Noise nz{0.001, 0.0, 0.05};
  int alarms = 0, whiteness = 0, diagnoses = 0;
  std::string why;
  for (std::uint64_t s = 700; s <= 719; ++s) {
    const std::vector<model::RunData> r = {run("exp1", 10 * s + 1, nz, ""), run("exp2", 10 * s + 2, nz, ""), run("exp3", 10 * s + 3, nz, "")};
    auto m = model::fit(r[0], *model::parse_terms("paper"));
    REQUIRE(m);
    auto d = wb::diagnose(*m, r[0], std::span<const model::RunData>(r).subspan(1));
    REQUIRE(d);
    ++diagnoses;
    for (const auto& c : d->checks)
      for (const auto& x : c.reasons) whiteness += x.find("not white") != std::string::npos;
    if (!d->adequate) {
      ++alarms;
      why += "seed " + std::to_string(s) + ":";
      for (const auto& x : d->reasons) why += " [" + x + "]";
      why += "\n";
    }
  }
  CHECK(diagnoses == 20);
  INFO(why);
  CHECK(whiteness == 0);
  CHECK(alarms <= 1);  // the goal: at most 5 %
}

TEST_CASE("workbench: a slow effect of the noise's size beside flicker is still found", "[noise]") {
  // The detection table's weakest row (docs/workbench.md "Whiteness and noise-factor alarms"):
  // a second thermal path 0.04*lp(T1,1600), about the size of the noise, hidden in every run of
  // a gyro with ARW 0.001 deg/sqrt(h) and bias instability 0.05 deg/h, seeds 600..605: NOT
  // ADEQUATE in 4 of 6 through fogctl (simulate, fit, diagnose) before and after the whiteness
  // statistic was high-passed; 3 of 6 here, in process, after. Slower than the test's 301 s,
  // it is the noise factor's and the search's.
  const Noise nz{0.001, 0.05, 0.0};
  int found = 0;
  for (std::uint64_t s = 600; s <= 605; ++s) {
    const std::vector<model::RunData> r = {run("exp1", 10 * s + 1, nz, "0.04*lp(T1,1600)"), run("exp2", 10 * s + 2, nz, "0.04*lp(T1,1600)"),
                                           run("exp3", 10 * s + 3, nz, "0.04*lp(T1,1600)")};
    auto m = model::fit(r[0], *model::parse_terms("paper"));
    REQUIRE(m);
    auto d = wb::diagnose(*m, r[0], std::span<const model::RunData>(r).subspan(1));
    REQUIRE(d);
    found += !d->adequate;
  }
  CHECK(found >= 3);
}

TEST_CASE("workbench: a hidden effect above the gyro's slow noise is still found", "[noise]") {
  // 0.05 deg/h per degC of absolute-temperature sensitivity (tests/sim/workbench_hidden_effect_test:
  // 2.1 x the no-effect level with AR noise) on a gyro with a rate random walk of 0.05
  // deg/h/sqrt(h): the walk's variance over a 3 h run, K^2 T / 21600 = 0.0013 (deg/h)^2, is far
  // below what the term removes (0.31^2 - 0.15^2 = 0.07), so the term is named.
  const Noise nz{0.0024, 0.0, 0.05};
  const std::vector<model::RunData> r = {run("exp1", 900, nz, "0.05*T1"), run("exp2", 901, nz, "0.05*T1"), run("exp3", 902, nz, "0.05*T1")};
  auto m = model::fit(r[0], *model::parse_terms("paper"));
  REQUIRE(m);
  auto d = wb::diagnose(*m, r[0], std::span<const model::RunData>(r).subspan(1));
  REQUIRE(d);
  INFO(d->summary);
  CHECK_FALSE(d->adequate);
  REQUIRE_FALSE(d->steps.empty());
  // T1 or one of its look-alikes on these profiles (T2, Ta, lp(T1,300): r > 0.99 once the
  // paper's terms are regressed out), named as the headline.
  const std::string first = d->steps.front().expr;
  CHECK((first == "T1" || first == "T2" || first == "Ta" || first.rfind("lp(T1", 0) == 0));
  CHECK(d->summary.find("Missing effect: " + d->steps.front().effect) == 0);
}

// A tool, hidden: the two false-alarm suites above (15 diagnoses over the corners, 20 on
// the corner the holds are blind to) with the floor's creep guard as NOISE_CREEP says (1 on,
// 0 off, unset: the default), printing each suite's alarms, verify's verdicts and every
// floor's creep statistic. docs/workbench.md "The noise floor".
TEST_CASE("workbench noise explore", "[.explore]") {
  wb::DiagnoseOptions o;
  model::VerifyOptions vo;
  if (const char* c = std::getenv("NOISE_CREEP"); c && *c) {
    o.failing.noise.floor.remove_creep = *c == '1';
    vo.noise.floor.remove_creep = *c == '1';
  }
  std::cout << "creep guard " << (o.failing.noise.floor.remove_creep ? "on" : "off") << "\n";
  auto one = [&](const Noise& nz, const std::vector<model::RunData>& r, const std::string& tag, int& alarms, int& verdicts) {
    auto m = model::fit(r[0], *model::parse_terms("paper"));
    REQUIRE(m);
    auto d = wb::diagnose(*m, r[0], std::span<const model::RunData>(r).subspan(1), o);
    REQUIRE(d);
    std::cout << tag << " ARW " << nz.arw_deg_per_sqrt_h << " B " << nz.bias_instability_dph << " RRW " << nz.rrw_dph_per_sqrt_h << ": "
              << (d->adequate ? "adequate" : "NOT ADEQUATE");
    for (const auto& c : d->checks) {
      const auto at = c.floor_note.find("creep");
      std::cout << " {" << c.run << " nf " << c.noise_factor << "/" << c.noise_limit_factor << (at != std::string::npos ? " " + c.floor_note.substr(at) : "") << "}";
    }
    std::cout << "\n";
    if (!d->adequate) {
      ++alarms;
      for (const auto& x : d->reasons) std::cout << "   [" << x << "]\n";
    }
    for (const auto& x : r) {
      auto v = model::verify(*m, x, vo);
      REQUIRE(v);
      if (v->noise_factor > v->noise_limit_factor || v->longest_fail_s >= 60.0) ++verdicts;
    }
  };
  int alarms = 0, verdicts = 0;
  const Noise cases[] = {{0.001, 0.0, 0.1}, {0.001, 0.05, 0.0}, {0.01, 0.05, 0.1}};
  std::uint64_t seed = 500;
  for (const auto& nz : cases)
    for (int k = 0; k < 5; ++k, seed += 10)
      one(nz, {run("exp1", seed, nz, ""), run("exp2", seed + 1, nz, ""), run("exp3", seed + 2, nz, "")}, "seed " + std::to_string(seed), alarms, verdicts);
  std::cout << "corners: " << alarms << " alarms in 15 diagnoses, " << verdicts << " verify verdicts in 45\n";
  int blind = 0, blind_verdicts = 0;
  const Noise nz{0.001, 0.05, 0.1};
  for (std::uint64_t s = 405; s <= 424; ++s)
    one(nz, {run("exp1", 10 * s + 1, nz, ""), run("exp2", 10 * s + 2, nz, ""), run("exp3", 10 * s + 3, nz, "")}, "s " + std::to_string(s), blind, blind_verdicts);
  std::cout << "blind corner: " << blind << " alarms in 20 diagnoses, " << blind_verdicts << " verify verdicts in 60\n";
}
