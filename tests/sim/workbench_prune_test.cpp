// Pruning by the one-column update (DiagnoseOptions::prune_fraction, docs/performance.md
// 2026-11-28): a candidate whose fall with the model's lags held is under a fraction of the
// smallest fall the detection rule accepts is not refitted. Whatever it skips, a full refit would
// not have detected nor chosen: the answer must be the one every candidate refitted gives, on
// cases near the rule's thresholds (hidden effects well under the noise floor, where the
// candidates' falls sit near the 1 %, 2 % and 5 % of the rules), with and without held-out runs.
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

model::RunData sim_run(const std::string& profile, std::uint64_t seed, const std::string& effect) {
  sim::SimConfig cfg;
  cfg.seed = seed;
  cfg.units[0].effects = effect;
  auto r = sim::simulate(cfg, fogbench::test::program(profile));
  REQUIRE(r);
  model::RunData d = r->front();
  d.name = profile;
  return d;
}

wb::Diagnosis diagnose(const std::vector<model::RunData>& r, const wb::DiagnoseOptions& o) {
  auto m = model::fit(r[0], *model::parse_terms("paper"));
  REQUIRE(m);
  auto d = wb::diagnose(*m, r[0], std::span<const model::RunData>(r).subspan(1), o);
  REQUIRE(d);
  return *d;
}

}  // namespace

TEST_CASE("workbench prune: candidates not refitted by their one-column update change no answer, near the rule's thresholds too") {
  struct Case {
    std::string effect;
    std::uint64_t seed;
    bool alone;  // the fit run only (the 5 % rule)
  };
  int pruned_total = 0;
  for (const auto& c : {Case{"0.004*T1", 41, false}, Case{"0.01*d(T1)", 43, false}, Case{"0.006*Ta", 45, true},
                        Case{"0.008*T1", 49, true}, Case{"", 47, false}}) {
    CAPTURE(c.effect, c.seed, c.alone);
    std::vector<model::RunData> r{sim_run("exp1", c.seed, c.effect)};
    if (!c.alone) {
      r.push_back(sim_run("exp2", c.seed + 1, c.effect));
      r.push_back(sim_run("exp3", c.seed + 2, c.effect));
    }
    wb::DiagnoseOptions every;
    every.prune_fraction = 0.0;
    const wb::Diagnosis full = diagnose(r, every);
    const wb::Diagnosis pruned = diagnose(r, {});
    CHECK(pruned.adequate == full.adequate);
    CHECK(pruned.final_terms == full.final_terms);
    REQUIRE(pruned.steps.size() == full.steps.size());
    CHECK(pruned.summary == full.summary);
    REQUIRE(pruned.candidates.size() == full.candidates.size());
    // The candidate named first, when detected (with nothing detected the first is the best BIC
    // among those refitted, and a pruned one is no longer among them).
    if (!full.candidates.empty() && full.candidates.front().detected) {
      CHECK(pruned.candidates.front().detected);
      CHECK(pruned.candidates.front().term == full.candidates.front().term);
    }
    // Each candidate not refitted: refitted in full it is not detected, and its fall on the fit
    // run is under the smallest the rules accept (so no step could have chosen it).
    const wb::DiagnoseOptions o;
    const double floor = c.alone ? o.min_fit_fall_alone : std::min(o.min_fit_fall, o.min_fit_fall_pooled);
    for (const auto& pc : pruned.candidates) {
      if (!pc.skipped.starts_with("not refitted")) continue;
      ++pruned_total;
      CAPTURE(pc.expr, pc.skipped);
      auto fc = std::find_if(full.candidates.begin(), full.candidates.end(),
                             [&](const wb::Candidate& x) { return x.expr == pc.expr && x.second_lag == pc.second_lag; });
      REQUIRE(fc != full.candidates.end());
      CHECK_FALSE(fc->detected);
      CHECK(fc->fall < floor);
    }
  }
  // The cases do exercise the pruning.
  CHECK(pruned_total > 0);
}
