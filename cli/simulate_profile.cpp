// A profile run on the simulated bench, closed loop (see simulate_profile.hpp).
#include "simulate_profile.hpp"

#include <cmath>

#include "fogbench/profiles/executor.hpp"
#include "fogbench/storage/run_data.hpp"

namespace fogbench::cli {

std::expected<SimulatedRun, std::string> simulate_profile(const profiles::Profile& profile, const sim::SimConfig& cfg,
                                                          const std::function<void(double, double)>& progress) {
  auto world = sim::World::create(cfg);
  if (!world) return std::unexpected(world.error());
  profiles::Executor ex(profile);
  const std::size_t nu = world->units();
  // Each second: the executor decides the setpoint from what the bench reads now, then the
  // world advances one second under it and the second's sample is recorded.
  std::vector<sim::SetpointSample> program;
  std::vector<std::vector<double>> t1(nu), t2(nu), gyro(nu), true_t1(nu);
  std::vector<double> chamber;
  profiles::Readings readings;
  readings.chamber_c = world->chamber_reading_c();
  for (std::size_t u = 0; u < nu; ++u) readings.coils.push_back({world->true_t1_c(u), world->true_t2_c(u)});
  const double total = profile.nominal_duration_s();
  // A profile that never ends would loop forever: bound it by its nominal length plus every
  // settle's timeout (the executor fails a settle at its timeout).
  double bound = total;
  for (const auto& s : profile.steps)
    if (const auto* st = std::get_if<profiles::SettleStep>(&s.action)) bound += st->timeout_s;
  SimulatedRun out;
  bool leading_settle = true;
  for (double t = 0.0;; t += 1.0) {
    const profiles::ExecutorStatus st = ex.update(t, readings);
    if (st.failed) return std::unexpected("profile " + profile.source_name + " failed at " + std::to_string(static_cast<long>(t)) + " s: " + st.failure_reason);
    if (st.finished) break;
    if (t > bound + 1.0) return std::unexpected("profile did not finish within its nominal time and timeouts");
    world->step(st.setpoint_c);
    const double reading = world->chamber_reading_c();
    readings.chamber_c = reading;
    for (std::size_t u = 0; u < nu; ++u) {
      const auto s = world->sample(u);
      readings.coils[u] = {s.t1_c, s.t2_c};
    }
    if (leading_settle && st.phase == profiles::Phase::settle) {
      out.settle_s = t + 1.0;
      continue;
    }
    leading_settle = false;
    program.push_back({st.setpoint_c, storage::model_phase(st.phase), static_cast<int>(st.step_index)});
    chamber.push_back(reading);
    for (std::size_t u = 0; u < nu; ++u) {
      const auto s = world->sample(u);
      t1[u].push_back(s.t1_c);
      true_t1[u].push_back(world->true_t1_c(u));
      t2[u].push_back(s.t2_c);
      gyro[u].push_back(s.gyro_dph);
    }
    if (progress && static_cast<long>(t) % 600 == 0) progress(t, total);
  }
  out.true_t1_c = std::move(true_t1);
  for (std::size_t u = 0; u < nu; ++u) {
    model::RunData r;
    r.name = cfg.units[u].serial;
    const std::size_t n = program.size();
    for (std::size_t i = 0; i < n; ++i) {
      r.time_s.push_back(static_cast<double>(i));
      r.setpoint_c.push_back(program[i].setpoint_c);
      r.phase.push_back(program[i].phase);
      r.step.push_back(program[i].step);
    }
    r.chamber_c = chamber;
    r.t1_c = std::move(t1[u]);
    r.t2_c = std::move(t2[u]);
    r.gyro_dph = std::move(gyro[u]);
    out.units.push_back(std::move(r));
  }
  return out;
}

}  // namespace fogbench::cli
