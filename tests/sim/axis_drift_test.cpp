// A three-axis unit's own drift per axis in the stepped world (UnitParams::axis_effects, what the
// mock bench adds to its y and z frames): evaluated as the unit's drift is, and leaving the
// unit's own output (axis x) untouched.
#include <catch2/catch.hpp>

#include <cmath>

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

namespace {

// Three coils' temperatures, degC: x's a slow sine, y's and z's lagging it by 20 s and 45 s.
struct AxisTemps {
  std::vector<double> t1[3], t2[3], ta;
  explicit AxisTemps(std::size_t n) {
    for (std::size_t i = 0; i < n; ++i) {
      const double x = static_cast<double>(i);
      for (std::size_t k = 0; k < 3; ++k) {
        const double late = x - (k == 0 ? 0.0 : k == 1 ? 20.0 : 45.0);
        t1[k].push_back(25.0 + 3.0 * std::sin(late / 90.0));
        t2[k].push_back(26.0 + 2.0 * std::cos(late / 70.0));
      }
      ta.push_back(27.0);
    }
  }
  sim::AxisCoilTemps spans() const {
    sim::AxisCoilTemps a;
    for (std::size_t k = 0; k < 3; ++k) {
      a.t1_c[k] = t1[k];
      a.t2_c[k] = t2[k];
    }
    return a;
  }
};

}  // namespace

TEST_CASE("sim drift_series: a cross-axis term is the model's evaluation of the axis's thermistors at its lag", "[axes][cross_axis]") {
  const AxisTemps temps(600);
  auto parsed = sim::parse_axis_effects(std::vector<std::string>{"x=0.3*T1y@20 + 0.1*d(T2z)@5", "y=0.05*T1"}, true);
  REQUIRE(parsed);
  // The parsed terms come back with their coefficients and lags, the text as given.
  REQUIRE(parsed->terms[0].size() == 2);
  CHECK(parsed->terms[0][0].coef == 0.3);
  CHECK(parsed->terms[0][0].lag.seconds == 20);
  CHECK(parsed->terms[0][1].lag.seconds == 5);
  CHECK(parsed->text[0] == "0.3*T1y@20 + 0.1*d(T2z)@5");
  CHECK(parsed->terms[1].size() == 1);
  CHECK(parsed->terms[2].empty());

  sim::DriftLaw law;  // mu0 0, Tref 20 degC
  law.terms = parsed->terms[0];
  auto d = sim::drift_series(law, temps.t1[0], temps.t2[0], temps.ta, temps.spans());
  REQUIRE(d);
  // Expected: the model's own evaluation of each term on the deviations from Tref (20 degC),
  // the value lag seconds earlier (the first sample before the run's start), times its coefficient.
  model::Signals s;
  std::vector<double> dev1[3], dev2[3];
  for (std::size_t k = 0; k < 3; ++k) {
    for (std::size_t i = 0; i < 600; ++i) {
      dev1[k].push_back(temps.t1[k][i] - 20.0);
      dev2[k].push_back(temps.t2[k][i] - 20.0);
    }
    s.axis_t1[k] = dev1[k];
    s.axis_t2[k] = dev2[k];
  }
  s.t1 = dev1[0];
  s.t2 = dev2[0];
  auto y = model::evaluate(*law.terms[0].expr, s);
  auto z = model::evaluate(*law.terms[1].expr, s);
  REQUIRE(y);
  REQUIRE(z);
  for (std::size_t i : {0u, 4u, 5u, 19u, 20u, 21u, 300u, 599u}) {
    const double want = 0.3 * (*y)[i >= 20 ? i - 20 : 0] + 0.1 * (*z)[i >= 5 ? i - 5 : 0];
    CHECK((*d)[i] == Approx(want).margin(1e-12));
  }
  // T1y at sample 100 is y's own coil (lagging x's by 20 s), not x's: 0.3 * (t1_y - 20) at 80.
  CHECK((*d)[100] - 0.1 * (*z)[95] == Approx(0.3 * (temps.t1[1][80] - 20.0)).margin(1e-12));
  CHECK(std::abs(temps.t1[1][80] - temps.t1[0][80]) > 0.1);  // the two coils differ there
}

TEST_CASE("sim drift_series: a cross-axis term without per-axis thermistors, or a short column, is refused naming it", "[axes][cross_axis]") {
  const AxisTemps temps(200);
  sim::UnitParams p;
  p.gyro.terms.clear();
  p.effects = "0.3*T1y";
  auto law = sim::make_drift_law(p);
  REQUIRE(law);
  auto none = sim::drift_series(*law, temps.t1[0], temps.t2[0], temps.ta);
  REQUIRE_FALSE(none);
  CHECK_THAT(none.error(), Catch::Contains("T1y") && Catch::Contains("did not record"));
  auto a = temps.spans();
  a.t2_c[2] = a.t2_c[2].first(150);
  auto short_z = sim::drift_series(*law, temps.t1[0], temps.t2[0], temps.ta, a);
  REQUIRE_FALSE(short_z);
  CHECK_THAT(short_z.error(), Catch::Contains("axis z") && Catch::Contains("150"));
  // Without the flag the option is refused before any simulation, naming the option.
  auto shared = sim::parse_axis_effects(std::vector<std::string>{"x=0.3*T1y"});
  REQUIRE_FALSE(shared);
  CHECK_THAT(shared.error(), Catch::Contains("--axis-effect x=0.3*T1y") && Catch::Contains("own coil thermistor"));
}

namespace {

// A lumped three-axis unit whose y and z have coils of their own, deeper in the housing.
sim::SimConfig axis_coil_config(std::string x_effects) {
  sim::SimConfig cfg = axis_drift_config({"", ""});
  auto& u = cfg.units[0];
  u.axis_coils = std::array{sim::deeper_in_housing(u.coil, 1), sim::deeper_in_housing(u.coil, 2)};
  u.x_effects = std::move(x_effects);
  return cfg;
}

}  // namespace

TEST_CASE("sim World with coils per axis: y's and z's coils lag x's, x's own cross-axis drift reads y's coil", "[axes][cross_axis]") {
  auto with = sim::World::create(axis_coil_config("1*T1y"));
  auto without = sim::World::create(axis_coil_config(""));
  REQUIRE(with);
  REQUIRE(without);
  REQUIRE(with->has_axis_coils(0));
  for (int i = 0; i < 120; ++i) {
    with->step(30.0);
    without->step(30.0);
  }
  // At rest at 30 degC: T1y - Tref = 10 degC, so x's own drift is 10 deg/h and x's output is
  // the same world's (same seed, same draws) plus exactly that; y's coil reads as x's, so the
  // unit's drift read on it differs by nothing.
  CHECK(with->axis_drift_dph(0, 0) == Approx(10.0).margin(1e-9));
  CHECK(with->sample(0).gyro_dph - without->sample(0).gyro_dph == Approx(10.0).margin(1e-9));
  CHECK(with->axis_drift_dph(0, 1) == Approx(0.0).margin(1e-9));
  CHECK(with->sample(0).axis_t1_c[0] == Approx(30.0).margin(0.03));  // 6 sigma of 0.005 degC
  // Heating: the air leads, x's coil follows, y's (1.6x slower) and z's (2.4x) later still.
  for (int i = 0; i < 300; ++i) with->step(60.0);
  const double tx = with->true_t1_c(0), ty = with->true_axis_t1_c(0, 1), tz = with->true_axis_t1_c(0, 2);
  CHECK(tx > ty + 0.5);
  CHECK(ty > tz + 0.5);
  CHECK(with->sample(0).axis_t1_c[0] == Approx(ty).margin(0.03));
  CHECK(with->axis_drift_dph(0, 0) == Approx(ty - 20.0).margin(1e-9));
  // The paper's terms read on y's slower coil give y a drift of its own on the ramp.
  CHECK(std::abs(with->axis_drift_dph(0, 1)) > 0.01);
}

TEST_CASE("sim World: a cross-axis term on a unit whose axes share one coil is refused naming the axis", "[axes][cross_axis]") {
  auto cfg = axis_drift_config({"", ""});
  cfg.units[0].x_effects = "0.1*T1y";
  auto w = sim::World::create(cfg);
  REQUIRE_FALSE(w);
  CHECK_THAT(w.error(), Catch::Contains("SIM-0001") && Catch::Contains("axis x") && Catch::Contains("share one coil"));
}
