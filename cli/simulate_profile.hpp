// Closes the loop between a temperature profile and the simulated bench: the profile's
// executor reads the simulated chamber and coils each second and commands the setpoint,
// exactly as the daemon will do with the real hardware.
#pragma once

#include <expected>
#include <functional>
#include <string>
#include <vector>

#include "fogbench/model/run.hpp"
#include "fogbench/profiles/profile.hpp"
#include "fogbench/sim/sim.hpp"

namespace fogbench::cli {

struct SimulatedRun {
  std::vector<model::RunData> units;  // one run per simulated unit
  double settle_s = 0.0;              // time spent in the opening settle, s (not in the runs)
  std::vector<std::vector<double>> true_t1_c;  // each unit's true (noiseless) T1 at each sample, degC
};

// Runs the profile to its end (or its failure) and returns each unit's run. The opening
// settle is simulated but left out of the runs, which start with the first hold as the
// paper's records do (time_s from 0). `progress(elapsed_s, total_s)` is called now and then.
std::expected<SimulatedRun, std::string> simulate_profile(
    const profiles::Profile& profile, const sim::SimConfig& cfg,
    const std::function<void(double, double)>& progress = {});

}  // namespace fogbench::cli
