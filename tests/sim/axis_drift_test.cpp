// A three-axis unit's own drift per axis in the stepped world (UnitParams::axis_effects, what the
// mock bench adds to its y and z frames): evaluated as the unit's drift is, and leaving the
// unit's own output (axis x) untouched.
#include <catch2/catch.hpp>

#include "fogbench/sim/sim.hpp"

using namespace fogbench;

namespace {

sim::SimConfig axis_drift_config(std::array<std::string, 2> axis_effects) {
  sim::SimConfig cfg;
  cfg.start_c = 30.0;  // at rest 10 degC above the truth's tref (20 degC)
  cfg.units[0].coil.model = sim::CoilModel::lumped;
  cfg.units[0].axis_effects = std::move(axis_effects);
  return cfg;
}

}  // namespace

TEST_CASE("sim axis_effects: y and z drift of their own, x's output unchanged", "[axes]") {
  // At rest at 30 degC, T1 - tref is 10 degC: "1*T1" is 10 deg/h, "-0.5*T1 + 0.2*T2" -3 deg/h.
  auto with = sim::World::create(axis_drift_config({"1*T1", "-0.5*T1 + 0.2*T2"}));
  auto without = sim::World::create(axis_drift_config({"", ""}));
  REQUIRE(with);
  REQUIRE(without);
  for (int s = 0; s < 200; ++s) {
    with->step(30.0);
    without->step(30.0);
    // Same seed, same draws: the axes' own laws draw nothing and change nothing of x.
    REQUIRE(with->sample(0).gyro_dph == without->sample(0).gyro_dph);
  }
  CHECK(with->axis_drift_dph(0, 1) == Approx(10.0).margin(1e-9));
  CHECK(with->axis_drift_dph(0, 2) == Approx(-3.0).margin(1e-9));
  CHECK(without->axis_drift_dph(0, 1) == 0.0);
  CHECK(without->axis_drift_dph(0, 2) == 0.0);
}

TEST_CASE("sim axis_effects: a bad term is refused naming the unit and the axis", "[axes]") {
  auto w = sim::World::create(axis_drift_config({"", "0.1*T9"}));
  REQUIRE_FALSE(w);
  CHECK_THAT(w.error(), Catch::Contains("SIM-0001") && Catch::Contains("axis z"));
  auto a = sim::World::create(axis_drift_config({"0.1*T1@auto", ""}));
  REQUIRE_FALSE(a);
  CHECK_THAT(a.error(), Catch::Contains("axis y") && Catch::Contains("fixed lag"));
}
