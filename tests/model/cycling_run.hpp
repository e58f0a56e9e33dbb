// A test run shared by the diagnose tests (tests/model/): temperature cycling with a term the
// paper's model lacks, generated in-process (model/ stays free of I/O, and so do its tests).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "fogbench/model/run.hpp"
#include "fogbench/model/terms.hpp"

namespace fogbench::model::test {

// A run of n s: a 20 min hold at 20 degC, then ramps of 1 degC/min between 10 and 30 degC with
// 20 min holds; the coil's wall follows the chamber through 150 s, the centre the wall through
// 40 s. The gyro: -8 deg/h - 3 deg/h per degC/min of d(T1) + 0.05 deg/h per degC of T1 (a term
// the paper's model lacks) + white noise of 0.146 deg/h.
inline RunData cycling_run(std::size_t n, std::uint64_t seed, const std::string& name_prefix) {
  RunData r;
  r.name = name_prefix + std::to_string(seed);
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, 0.146);
  double t2 = 20.0, t1 = 20.0, sp = 20.0, target = 20.0;
  int step = 0;
  std::size_t held_since = 0;
  for (std::size_t t = 0; t < n; ++t) {
    Phase ph = Phase::hold;
    if (t >= 1200 && sp == target && t - held_since >= 1200) {
      target = target <= 10.0 ? 30.0 : 10.0;
      ++step;
    }
    if (sp != target) {
      sp += target > sp ? std::min(1.0 / 60.0, target - sp) : -std::min(1.0 / 60.0, sp - target);
      ph = target > sp ? Phase::heating : Phase::cooling;
      if (sp == target) held_since = t;
    }
    t2 += (sp - t2) * (1.0 - std::exp(-1.0 / 150.0));
    t1 += (t2 - t1) * (1.0 - std::exp(-1.0 / 40.0));
    r.time_s.push_back(static_cast<double>(t));
    r.t1_c.push_back(t1);
    r.t2_c.push_back(t2);
    r.setpoint_c.push_back(sp);
    r.step.push_back(step);
    r.phase.push_back(ph);
  }
  const auto rate = derivative_per_min(r.t1_c, 1.0);
  for (std::size_t t = 0; t < n; ++t) r.gyro_dph.push_back(-8.0 - 3.0 * rate[t] + 0.05 * (r.t1_c[t] - 20.0) + noise(rng));
  return r;
}

}  // namespace fogbench::model::test
