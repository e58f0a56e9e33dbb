// The simulated gyro's true scale factor and the rate sequence (sim/src/scale_factor.cpp):
// values derived by hand, the short tail of a profile step, and bad sequences named by item.
#include <catch2/catch.hpp>

#include "fogbench/sim/scale_factor.hpp"

using namespace fogbench::sim;
using Catch::Matchers::Contains;

TEST_CASE("sim scale factor: temperature, temperature rate, nonlinearity and asymmetry as documented", "[scale_factor]") {
  ScaleFactorTruth t;
  t.sf0 = 1.0001;
  t.tc_ppm_per_c = 10.0;
  t.tc2_ppm_per_c2 = 0.5;
  t.temp_rate_ppm_per_c_per_min = 20.0;
  // At 30 degC (dT 10) and 0.5 degC/min: 1.0001 (1 + 1e-6 (100 + 50 + 10)).
  CHECK(scale_factor(t, 30.0, 0.5) == Approx(1.0001 * (1.0 + 160e-6)).epsilon(1e-14));
  t.nl_ppm = 40.0;
  t.asymmetry_ppm = 200.0;
  // At +150 deg/s, 20 degC, no rate: 1.0001 (1 + 40e-6 x 0.25) (1 + 100e-6) 150; at -150 the asymmetry's sign flips.
  CHECK(indicated_rate_dps(t, 150.0, 20.0, 0.0) == Approx(1.0001 * (1.0 + 10e-6) * (1.0 + 100e-6) * 150.0).epsilon(1e-14));
  CHECK(indicated_rate_dps(t, -150.0, 20.0, 0.0) == Approx(-1.0001 * (1.0 + 10e-6) * (1.0 - 100e-6) * 150.0).epsilon(1e-14));
  CHECK(indicated_rate_dps(t, 0.0, 20.0, 0.0) == 0.0);
}

TEST_CASE("sim rate sequence: cycled from the step's start, a short tail stays at the rate before it", "[scale_factor]") {
  auto s = parse_rate_sequence(" 0, +10 ,-10", 20.0);
  REQUIRE(s);
  REQUIRE(s->rates_dps == std::vector<double>{0.0, 10.0, -10.0});
  CHECK(s->rate_at(0.0, 200.0) == 0.0);
  CHECK(s->rate_at(25.0, 200.0) == 10.0);
  CHECK(s->rate_at(65.0, 200.0) == 0.0);  // the fourth rate step: the sequence again
  // A 70 s profile step holds 3 whole rate steps: its last 10 s stay at -10 deg/s.
  CHECK(s->rate_at(65.0, 70.0) == -10.0);
  CHECK_THAT(parse_rate_sequence("0,1e9", 20.0).error(), Contains("rate 2") && Contains("beyond"));
  CHECK_THAT(parse_rate_sequence("0,,1", 20.0).error(), Contains("rate 2: ''"));
  CHECK_THAT(parse_rate_sequence("0,1", 0.0).error(), Contains("positive number of seconds"));
}
