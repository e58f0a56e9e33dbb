// Issue 25 point 4: several hidden effects at once, of different families (level, rate at a
// delay, power, product, heating/cooling asymmetry, slow path), some near the noise floor, on the
// lumped coil and on the distributed one (whose own field needs d(T2) and T1 beside the paper's
// terms): diagnose's greedy search names each effect (or a look-alike it names with it) and
// the model with its steps added, refitted on exp1 and applied unchanged to exp2 and exp3, is
// within 1.05 x the noise floor on every run. The floor of a run is the paper's model on the
// lumped coil with the same seed and no effect (the coil draws no random numbers, so the noise
// is the same sample for sample): the compensated std of the exact truth. One or two seeds a
// case, different across cases (the test suite is near CI's time wall); docs/workbench.md
// "Several effects at once" has the figures over more seeds.
#include <catch2/catch.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <iostream>
#include <sstream>

#include "fogbench/model/model.hpp"
#include "fogbench/model/workbench.hpp"
#include "fogbench/sim/sim.hpp"
#include "programs.hpp"

using namespace fogbench;
namespace wb = model::workbench;

namespace {

using fogbench::test::program;

model::RunData run(const std::string& profile, std::uint64_t seed, const std::string& effect, sim::CoilModel coil) {
  sim::SimConfig cfg;
  cfg.seed = seed;
  cfg.units[0].effects = effect;
  cfg.units[0].coil.model = coil;
  auto r = sim::simulate(cfg, program(profile));
  REQUIRE(r);
  model::RunData d = r->front();
  d.name = profile;
  return d;
}

std::vector<model::RunData> runs(const std::string& effect, std::uint64_t seed, sim::CoilModel coil) {
  return {run("exp1", seed, effect, coil), run("exp2", seed + 1, effect, coil), run("exp3", seed + 2, effect, coil)};
}

double comp_std(const model::Model& m, const model::RunData& r) {
  auto v = model::verify(m, r);
  REQUIRE(v);
  return v->run.comp_std;
}


// The model with the search's steps added with add_term as printed (what a user does).
model::Model with_steps(const model::Model& m0, const wb::Diagnosis& d, const model::RunData& fit_run) {
  model::Model m = m0;
  for (const auto& st : d.steps) {
    auto a = wb::add_term(m, fit_run, st.added);
    REQUIRE(a);
    m = a->model;
  }
  return m;
}

// One effect's family: a step's term, or one of its named look-alikes, spelled by one of these.
bool found(const wb::Diagnosis& d, const std::vector<std::string>& family) {
  auto in = [&](const std::string& t) {
    for (const auto& f : family)
      if (t == f || t.rfind(f + "@", 0) == 0) return true;
    return false;
  };
  for (const auto& st : d.steps) {
    if (in(st.expr) || in(st.added)) return true;
    for (const auto& l : st.look_alikes)
      if (in(l)) return true;
  }
  return false;
}

struct Case {
  std::string effect;
  sim::CoilModel coil;
  std::vector<std::vector<std::string>> families;  // one per hidden effect
  std::vector<std::uint64_t> seeds;
};

void check_case(const Case& k) {
  for (auto seed : k.seeds) {
    INFO("[" << k.effect << "] " << (k.coil == sim::CoilModel::distributed ? "distributed" : "lumped") << " coil, seed " << seed);
    const auto r = runs(k.effect, seed, k.coil);
    const auto clean = runs("", seed, sim::CoilModel::lumped);
    auto truth = model::fit(clean[0], *model::parse_terms("paper"));
    REQUIRE(truth);
    auto m = model::fit(r[0], *model::parse_terms("paper"));
    REQUIRE(m);
    wb::DiagnoseOptions o;
    o.threads = 2;
    auto d = wb::diagnose(*m, r[0], std::span<const model::RunData>(r).subspan(1), o);
    REQUIRE(d);
    INFO(d->summary);
    CHECK_FALSE(d->adequate);  // the paper's model misses them
    for (const auto& fam : k.families) {
      INFO("family of " << fam.front());
      CHECK(found(*d, fam));
    }
    const model::Model fm = with_steps(*m, *d, r[0]);
    INFO("final model " << fm.terms_string());
    for (std::size_t i = 0; i < 3; ++i) {
      const double ratio = comp_std(fm, r[i]) / comp_std(*truth, clean[i]);
      INFO(r[i].name << ": " << ratio << " x the floor");
      CHECK(ratio <= 1.05);
    }
  }
}

const std::vector<std::string> kLevel{"T1", "T2", "Ta", "lp(T1,300)"};
const std::vector<std::string> kProduct{"T1*d(T1)"};
const std::vector<std::string> kHysteresis{"up(d(T1))", "down(d(T1))"};

}  // namespace

// Sizes: each pair takes the paper model's compensated std to about 2 x the floor on exp1
// (1.35 to 3 x over the runs), the near-floor pair to 1.3 to 1.4 x on exp1 and 1.1 to 1.15 x on
// exp2 (diagnose's noise factor, measured 2026-11-28).
TEST_CASE("workbench, several effects at once on the lumped coil: each found, every run within 1.05 x the floor") {
  check_case({"0.03*T1 + 0.05*T1*d(T1)", sim::CoilModel::lumped, {kLevel, kProduct}, {7}});
  check_case({"0.012*T1 + 0.03*T1*d(T1)", sim::CoilModel::lumped, {kLevel, kProduct}, {7, 21}});
  check_case({"0.003*T1^2 + -1.0*up(d(T1))", sim::CoilModel::lumped, {{"T1^2", "Ta^2", "T2^2"}, kHysteresis}, {21}});
  check_case({"0.004*T1*T2 + 0.6*down(d(T1))", sim::CoilModel::lumped, {{"T1*T2", "T1*Ta", "T2*Ta", "T1^2"}, kHysteresis}, {7}});
}

TEST_CASE("workbench, three effects at once (slow path, product, power) on the lumped coil: within 1.05 x the floor") {
  // lp(T1,300) is named T1@~310 (a 300 s low-pass of a ramp is the ramp 300 s late), T1^2 as
  // Ta^2 beside T1^2 at a lag: T1*d(T1) is their difference (d(T1^2) = 2 T1 d(T1)), spelled by
  // the pair rather than named; what is asserted for it is the floor.
  check_case({"0.03*lp(T1,300) + 0.05*T1*d(T1) + 0.004*T1^2", sim::CoilModel::lumped,
              {{"T1", "lp(T1,300)"}, {"T1^2", "Ta^2", "T2^2"}}, {21}});
}

TEST_CASE("workbench, a slow path beside a product, and a step that spells two effects (backfitting): within 1.05 x the floor") {
  check_case({"0.05*lp(T1,1600) + 0.02*T1*d(T1)", sim::CoilModel::lumped,
              {{"lp(T1,1600)", "lp(Ta,1600)", "lp(T1,900)", "lp(Ta,900)", "lp(T1,2700)", "lp(Ta,2700)"}, kProduct}, {7}});
  // A rate at a 300 s delay beside a level: on seed 21 the first step, d(lp(grad,2700))@310,
  // takes exp1 to its floor and leaves exp3 at 1.17 x with no single term falling 1% more;
  // backfitting replaces it (d(lp(grad,1600))@358, lp(T1,2700)@600, d(Ta)@367: look-alikes of
  // the two, named as such). What is asserted is the floor.
  check_case({"-1.5*d(T1)@300 + 0.03*T1", sim::CoilModel::lumped, {}, {21}});
}

TEST_CASE("workbench on the distributed coil with effects beside its own: every run within 1.05 x the floor") {
  // The field alone needs d(T2) and T1 beside the paper's terms (workbench_coil_test.cpp).
  check_case({"", sim::CoilModel::distributed, {}, {21}});
  // A product near the floor beside the field's own terms: after d(T2) and T1, exp1 falls 4%
  // and exp2 0.6% with T1*d(T1); the per-run rule (every held-out run 1%) had stopped
  // the loop at 1.10 x on exp3 (seed 1): the pooled rule finds it.
  check_case({"0.02*T1*d(T1)", sim::CoilModel::distributed, {kProduct}, {1}});
  check_case({"0.01*T1 + 0.003*T1^2", sim::CoilModel::distributed, {{"T1^2", "Ta^2", "T2^2"}}, {7}});
}

// A tool, hidden: MULTI_CASES="effect|D:effect" (D: the distributed coil) and MULTI_SEEDS="7 21" print
// where the search stops on each and why (steps, final ratios, the next round's candidates, the
// noise floor each model reads); MULTI_CREEP=0 reads the floor with the thermistors' creep left in
// (1: taken out, the default); MULTI_MAX_TERMS=N searches up to N steps (default 5).
TEST_CASE("workbench multi explore", "[.explore]") {
  const char* env = std::getenv("MULTI_CASES");
  std::vector<std::string> cases;
  {
    std::stringstream ss(env ? env : "");
    std::string line;
    while (std::getline(ss, line, '|')) cases.push_back(line);
  }
  const char* seeds_env = std::getenv("MULTI_SEEDS");
  std::vector<std::uint64_t> seeds;
  {
    std::stringstream ss(seeds_env ? seeds_env : "7");
    std::uint64_t s;
    while (ss >> s) seeds.push_back(s);
  }
  for (const auto& spec : cases) {
    const bool dist = spec.rfind("D:", 0) == 0;
    const std::string effect = dist ? spec.substr(2) : spec;
    const auto coil = dist ? sim::CoilModel::distributed : sim::CoilModel::lumped;
    for (auto seed : seeds) {
      const auto r = runs(effect, seed, coil);
      const auto clean = runs("", seed, sim::CoilModel::lumped);
      auto truth = model::fit(clean[0], *model::parse_terms("paper"));
      REQUIRE(truth);
      auto m = model::fit(r[0], *model::parse_terms("paper"));
      REQUIRE(m);
      wb::DiagnoseOptions o;
      o.threads = 2;
      if (const char* c = std::getenv("MULTI_CREEP"); c && *c) o.failing.noise.floor.remove_creep = *c == '1';  // the thermistors' creep taken out of the floor (1) or not (0)
      if (const char* c = std::getenv("MULTI_MAX_TERMS"); c && *c) o.max_terms = std::atoi(c);
      auto t0 = std::chrono::steady_clock::now();
      auto d = wb::diagnose(*m, r[0], std::span<const model::RunData>(r).subspan(1), o);
      const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      REQUIRE(d);
      std::ostringstream out;
      out << (dist ? "DIST " : "LUMP ") << "[" << effect << "] seed " << seed << " (" << secs << " s)\n";
      out << "  before:";
      for (const auto& c : d->checks) out << " " << c.run << " " << c.noise_factor;
      out << "\n  steps:";
      for (const auto& s : d->steps) out << " +" << s.added << " (" << s.rms_before_dph << "->" << s.rms_after_dph << ")";
      out << "\n  final " << d->final_terms << "\n  final nf:";
      for (std::size_t i = 0; i < d->final_checks.size(); ++i) {
        const auto& c = d->final_checks[i];
        out << " " << c.run << " " << c.noise_factor << " (lim " << c.noise_limit_factor << ", lb p " << c.ljung_box_p << ", acf " << c.acf_rms
            << ", fails " << c.failures.size() << "; /true floor " << c.comp_std_dph / comp_std(*truth, clean[i]) << ")";
      }
      out << "\n  adequate " << d->adequate << " outside " << d->outside_search << "\n";
      int k = 0;
      for (const auto& c : d->candidates) {
        if (k++ >= 4) break;
        out << "   cand " << c.term << " det " << c.detected << " fall " << c.fall << " held " << c.held_out_fall << " dbic " << c.delta_bic << " p " << c.p_value << " | " << c.verdict << "\n";
      }
      out << "  summary: " << d->summary.substr(0, 400) << "\n";
      // The unit's noise floor as each model reads it (a wrong term's misfit in the holds reads
      // as slow noise), and on the lumped coil's clean runs under the paper's model (the truth).
      {
        auto pf = [&](const char* tag, const model::Model& mm, const std::vector<model::RunData>& on) {
          auto f = model::unit_noise_floor(mm, on, o.failing.noise.floor);
          if (!f) {
            out << "  floor " << tag << ": error\n";
            return;
          }
          const auto fv = model::floor_variance(*f, r[0].size(), 1);
          out << "  floor " << tag << " [" << mm.terms_string() << "]: white " << f->white_var_dph2 << " flick B " << f->bias_instability_dph << " rrw " << f->rrw_dph_per_sqrt_h << " bound " << f->rrw_bound_dph_per_sqrt_h << " total " << fv.total << " slow " << fv.slow << " sigma_a " << mm.sigma_a_dph << " creep chi2 " << f->creep_chi2 << (f->creep_removed ? " removed" : "") << "\n";
        };
        pf("base", *m, r);
        if (!d->steps.empty())
          if (auto a = wb::add_term(*m, r[0], d->steps[0].added)) pf("step1", a->model, r);
        pf("clean-truth", *truth, clean);
      }
      // The loop's next round: the final model, diagnosed again.
      model::Model fm = *m;
      for (const auto& st : d->steps) {
        auto a = wb::add_term(fm, r[0], st.added);
        REQUIRE(a);
        fm = a->model;
      }
      if (!d->steps.empty()) {
        auto d2 = wb::diagnose(fm, r[0], std::span<const model::RunData>(r).subspan(1), o);
        REQUIRE(d2);
        out << "  round2: adequate " << d2->adequate << " steps";
        for (const auto& s : d2->steps) out << " +" << s.added;
        out << "\n";
        for (const auto& rr : d2->reasons) out << "   reason: " << rr.substr(0, 300) << "\n";
        k = 0;
        for (const auto& c : d2->candidates) {
          if (k++ >= 4) break;
          out << "   cand " << c.term << " det " << c.detected << " fall " << c.fall << " held " << c.held_out_fall << " dbic " << c.delta_bic << " p " << c.p_value << " | " << c.verdict << "\n";
        }
      }
      std::cout << out.str() << std::flush;
    }
  }
}
