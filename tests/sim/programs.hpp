// Test helper shared by tests/sim: a shipped profile's setpoints at 1 s without the opening
// settle (a run starts at the first hold, as the paper's records do; the simulated coil
// starts at rest at the first setpoint).
#pragma once

#include <catch2/catch.hpp>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "fogbench/model/run.hpp"
#include "fogbench/profiles/profile.hpp"
#include "fogbench/sim/sim.hpp"

namespace fogbench::test {

inline std::vector<sim::SetpointSample> program(const std::string& name) {
  std::ifstream f(std::string(FOGBENCH_SOURCE_DIR) + "/profiles/" + name + ".profile");
  std::stringstream ss;
  ss << f.rdbuf();
  auto p = profiles::parse_profile(ss.str(), name);
  REQUIRE(p);
  std::vector<sim::SetpointSample> out;
  for (const auto& pt : profiles::nominal_setpoints(*p, 1.0)) {
    if (pt.phase == profiles::Phase::settle) continue;
    const model::Phase ph = pt.phase == profiles::Phase::heating   ? model::Phase::heating
                            : pt.phase == profiles::Phase::cooling ? model::Phase::cooling
                                                                   : model::Phase::hold;
    out.push_back({pt.setpoint_c, ph, static_cast<int>(pt.step_index)});
  }
  return out;
}

}  // namespace fogbench::test
