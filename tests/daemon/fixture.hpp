// Shared by the daemon's unit tests: the golden configuration, an in-memory store and a small
// synthetic bench whose drift follows the paper's model, so a station can run whole profiles
// without I/O and its fits can be checked against known coefficients.
#pragma once

#include <catch2/catch.hpp>

#include <cmath>
#include <fstream>
#include <random>
#include <sstream>
#include <string>

#include "fogbench/daemon/config.hpp"
#include "fogbench/daemon/station.hpp"
#include "fogbench/storage/store.hpp"

namespace fogbench::daemon::test {

inline std::filesystem::path golden_dir() {
  return std::filesystem::path(FOGBENCH_SOURCE_DIR) / "tests" / "golden";
}

inline nlohmann::json golden_config_json() {
  std::ifstream in(golden_dir() / "config.json");
  std::stringstream ss;
  ss << in.rdbuf();
  return nlohmann::json::parse(ss.str());
}

inline DaemonConfig golden_config(const nlohmann::json& patch = nlohmann::json::object()) {
  nlohmann::json j = golden_config_json();
  j.merge_patch(patch);
  auto c = parse_daemon_config(j, golden_dir());
  REQUIRE(c.has_value());
  return *c;
}

// The golden configuration's units with another gyro scale: its 1e-4 deg/h per count holds
// +-59.65 deg/s, short of a rate table's faster steps (refused at run.start and
// profile.validate); the shipped examples count in 1e-3 deg/h (+-596 deg/s).
// As a patch for golden_config: {"drivers": {"units": [...]}}.
inline nlohmann::json golden_units_at_scale(double scale_dph_per_count) {
  nlohmann::json units = golden_config_json()["drivers"]["units"];
  for (auto& u : units) u["gyro"]["scale_dph_per_count"] = scale_dph_per_count;
  return {{"units", units}};
}

inline storage::Store memory_store() {
  auto s = storage::Store::open(":memory:");
  REQUIRE(s.has_value());
  return std::move(*s);
}

// A chamber that follows its setpoint at up to 5 degC/min, and per unit a coil whose centre
// (T1, tau 240 s, from wall and air) and wall (T2, tau 60 s) lag the air; the gyro reads
//   y = mu0 + beta1 * dT1/dt [degC/min] + beta2 * (T1 - T2) + white noise sigma_dph (small beside the drift of a 5 degC excursion, so a verification passes).
// One step is one second. Deterministic (seeded).
struct SyntheticBench {
  double mu0_dph = -8.0, beta1 = -2.7, beta2 = -0.4, sigma_dph = 0.05;
  double air_c = 20.0;
  std::vector<double> t1_c, t2_c;
  std::mt19937_64 rng{42};
  std::normal_distribution<double> noise{0.0, 1.0};

  explicit SyntheticBench(std::size_t units) : t1_c(units, 20.0), t2_c(units, 20.0) {}

  TickInput step(double setpoint_c, double wall_time = 0.0) {
    const double max_step = 5.0 / 60.0;
    air_c += std::clamp(setpoint_c - air_c, -max_step, max_step);
    TickInput in;
    in.wall_time = wall_time;
    in.chamber_c = air_c;
    in.chamber_setpoint_c = setpoint_c;
    for (std::size_t i = 0; i < t1_c.size(); ++i) {
      const double t1_old = t1_c[i];
      t2_c[i] += (air_c - t2_c[i]) / 60.0;
      // The centre sees the wall and, through the mount, the air: so T1' is not a multiple of
      // T1 - T2 and the two terms of the paper's model are separable.
      t1_c[i] += (0.5 * (t2_c[i] + air_c) - t1_c[i]) / 240.0;
      const double rate_c_per_min = (t1_c[i] - t1_old) * 60.0;
      UnitReading u;
      u.gyro_dph = mu0_dph + beta1 * rate_c_per_min + beta2 * (t1_c[i] - t2_c[i]) + sigma_dph * noise(rng);
      u.frames = 100;
      u.t1_c = t1_c[i];
      u.t2_c = t2_c[i];
      in.units.push_back(u);
    }
    return in;
  }
};

// Ticks the station until its run ends or max_ticks pass; returns the ticks made.
inline int run_to_end(Station& st, SyntheticBench& bench, double& clock_s, int max_ticks = 100000) {
  double sp = st.status()["setpoint_c"].get<double>();
  int n = 0;
  while (n < max_ticks) {
    sp = st.tick(clock_s, bench.step(sp)).setpoint_c;
    clock_s += 1.0;
    ++n;
    if (!st.active_run_id()) break;
  }
  return n;
}

}  // namespace fogbench::daemon::test
