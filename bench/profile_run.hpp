// A profile's text simulated into a run, as the diagnose benchmarks make their inputs
// (bench_diagnose, bench_diagnose_peak): the profile's nominal setpoints at 1 s (its settle
// left out), the simulator's default gyro on the lumped coil, `effect` hidden in the drift.
#pragma once

#include <cstdint>
#include <expected>
#include <string>
#include <vector>

#include "fogbench/model/run.hpp"
#include "fogbench/profiles/profile.hpp"
#include "fogbench/sim/sim.hpp"

namespace fogbench::bench {

// `cycles` cycles of exp1's steps after a 10 min hold, a 40 min hold at the end; 48 cycles are
// three days (262,200 s at 1 Hz: the issue-25 case, docs/performance.md's long3d.profile).
inline std::string long_profile(int cycles = 48) {
  std::string t = "setpoint 20 C\nhold 10 min\n";
  for (int i = 0; i < cycles; ++i)
    t += "ramp to 10 C at 1 C/min\nhold 20 min\nramp to 30 C at 1 C/min\nhold 20 min\nramp to 20 C at 1 C/min\nhold 10 min\n";
  return t + "hold 40 min\n";
}

inline std::expected<model::RunData, std::string> simulate_profile_text(const std::string& text, const std::string& name,
                                                                        std::uint64_t seed, const std::string& effect) {
  auto p = profiles::parse_profile(text, name);
  if (!p) return std::unexpected("profile " + name + ": cannot parse");
  std::vector<sim::SetpointSample> prog;
  for (const auto& pt : profiles::nominal_setpoints(*p, 1.0)) {
    if (pt.phase == profiles::Phase::settle) continue;
    const model::Phase ph = pt.phase == profiles::Phase::heating   ? model::Phase::heating
                            : pt.phase == profiles::Phase::cooling ? model::Phase::cooling
                                                                   : model::Phase::hold;
    prog.push_back({pt.setpoint_c, ph, static_cast<int>(pt.step_index)});
  }
  sim::SimConfig cfg;
  cfg.seed = seed;
  cfg.units[0].effects = effect;
  auto r = sim::simulate(cfg, prog);
  if (!r) return std::unexpected("simulate " + name + ": " + r.error());
  auto run = r->front();
  run.name = name;
  return run;
}

}  // namespace fogbench::bench
