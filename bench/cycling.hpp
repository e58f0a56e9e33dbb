// The paper's cycling profile as the fit benchmarks simulate it (bench_fit, bench_fit_alloc):
// a 10 min hold, then 1 degC/min ramps between 10 and 30 degC separated by 20 min holds.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

#include "fogbench/model/run.hpp"
#include "fogbench/sim/sim.hpp"

namespace fogbench::bench {

// n one-second setpoints (degC) of the cycling profile, with their phases.
inline std::vector<sim::SetpointSample> cycling_program(std::size_t n) {
  std::vector<sim::SetpointSample> p;
  p.reserve(n);
  double sp = 20.0, target = 10.0;  // degC
  std::size_t hold_left = 600;      // s
  for (std::size_t i = 0; i < n; ++i) {
    model::Phase ph = model::Phase::hold;
    if (hold_left > 0) {
      --hold_left;
    } else {
      const double step = 1.0 / 60.0;  // degC per s: 1 degC/min
      ph = target > sp ? model::Phase::heating : model::Phase::cooling;
      sp += target > sp ? std::min(step, target - sp) : -std::min(step, sp - target);
      if (std::abs(sp - target) < 1e-9) {
        target = target < 20.0 ? 30.0 : 10.0;
        hold_left = 1200;
      }
    }
    p.push_back({sp, ph, 0});
  }
  return p;
}

}  // namespace fogbench::bench
