// Scale factor over temperature (model/src/scale_factor.cpp): IEEE Std 952's least-squares
// scale factor, nonlinearity and asymmetry on noiseless sequences whose values are derived in
// the comments, the temperature sensitivity and temperature-rate term across plateaus, and
// every bad input named by plateau and step.
#include <catch2/catch.hpp>
#include <cmath>
#include <functional>
#include <string>
#include <vector>

#include "fogbench/model/scale_factor.hpp"

namespace sf = fogbench::model::sf;
using Catch::Matchers::Contains;

namespace {

// Output of a gyro (deg/s) for input r (deg/s), coil temperature t (degC), temperature rate
// tdot (degC/min).
using Law = std::function<double(double r, double t, double tdot)>;

struct PlateauSpec {
  int id;
  double t_c;              // coil temperature at the plateau's middle, degC
  double tdot_c_per_min;   // constant over the plateau, degC/min
};

// Each plateau runs `rates` in order, `step_s` samples of 1 s each.
sf::RateRecord make(const std::vector<PlateauSpec>& plateaus, const std::vector<double>& rates, int step_s, const Law& law) {
  sf::RateRecord r;
  double t = 0.0;
  for (const auto& p : plateaus) {
    const double mid = t + 0.5 * static_cast<double>(rates.size() * static_cast<std::size_t>(step_s) - 1);
    for (double rate : rates)
      for (int k = 0; k < step_s; ++k, t += 1.0) {
        const double coil = p.t_c + p.tdot_c_per_min / 60.0 * (t - mid);
        r.time_s.push_back(t);
        r.plateau.push_back(p.id);
        r.rate_in_dps.push_back(rate);
        r.coil_c.push_back(coil);
        r.rate_out_dps.push_back(law(rate, coil, p.tdot_c_per_min));
      }
  }
  return r;
}

const std::vector<double> kRates = {0.0, 100.0, -100.0, 300.0, -300.0};

}  // namespace

TEST_CASE("scale factor: a linear gyro gives its slope and bias, no nonlinearity, no asymmetry", "[scale_factor]") {
  // out = 0.001 deg/s + 1.0001 r: SF 1.0001, bias 3.6 deg/h, NL 0, asymmetry 0.
  auto rec = make({{1, 20.0, 0.0}}, kRates, 20, [](double r, double, double) { return 0.001 + 1.0001 * r; });
  auto res = sf::fit(rec);
  REQUIRE(res);
  REQUIRE(res->plateaus.size() == 1);
  const auto& p = res->plateaus[0];
  CHECK(p.scale_factor == Approx(1.0001).epsilon(1e-12));
  CHECK(p.bias_dph == Approx(3.6).epsilon(1e-9));
  CHECK(p.bias_from_zero_rate);
  CHECK(std::abs(p.nonlinearity_ppm) < 1e-6);
  CHECK(std::abs(p.asymmetry_ppm) < 1e-6);
  CHECK(p.steps.size() == 5);
  // Settling: the first 5 s of each 20 s step dropped: 15 used per step.
  CHECK(p.steps[0].n_used == 15);
  CHECK(res->n_samples_dropped == 25);
  // One plateau: no temperature sensitivity, and the reason is given.
  CHECK_FALSE(res->tc_ppm_per_c.value);
  CHECK_THAT(res->tc_ppm_per_c.not_identified, Contains("plateaus"));
}

TEST_CASE("scale factor: a cubic nonlinearity gives the IEEE 952 nonlinearity in ppm of full-scale output", "[scale_factor]") {
  // out = r + c r^3, c = 1e-9 (deg/s)^-2, rates 0, +-100, +-300 (mean 0).
  // sum r^2 = 2e5, sum r^4 = 1.64e10: slope = 1 + c 1.64e10 / 2e5 = 1 + 8.2e-5 = 1.000082.
  // Residual r (c r^2 - 8.2e-5): at 100: -7.2e-3, at 300: +2.4e-3, at 0: 0; intercept 0.
  // NL = 7.2e-3 / (300 x 1.000082) x 1e6 = 23.99803 ppm; asymmetry 0 (odd function).
  auto rec = make({{3, 20.0, 0.0}}, kRates, 10, [](double r, double, double) { return r + 1e-9 * r * r * r; });
  auto res = sf::fit(rec);
  REQUIRE(res);
  const auto& p = res->plateaus[0];
  CHECK(p.scale_factor == Approx(1.000082).epsilon(1e-12));
  CHECK(p.nonlinearity_ppm == Approx(7.2e-3 / (300.0 * 1.000082) * 1e6).epsilon(1e-9));
  CHECK(p.full_scale_out_dps == Approx(300.0 * 1.000082).epsilon(1e-12));
  CHECK(std::abs(p.asymmetry_ppm) < 1e-6);
  CHECK(p.steps[1].residual_ppm_fso == Approx(-7.2e-3 / (300.0 * 1.000082) * 1e6).epsilon(1e-9));
}

TEST_CASE("scale factor: different positive and negative slopes give their asymmetry in ppm", "[scale_factor]") {
  // Positive inputs 1.0002 r, negative 0.9998 r, bias 0.002 deg/s (7.2 deg/h):
  // SF+ = 1.0002, SF- = 0.9998, asymmetry = 4e-4 / 1.0 = 400 ppm.
  auto rec = make({{0, 20.0, 0.0}}, kRates, 10, [](double r, double, double) { return 0.002 + (r > 0 ? 1.0002 : 0.9998) * r; });
  auto res = sf::fit(rec);
  REQUIRE(res);
  const auto& p = res->plateaus[0];
  CHECK(p.sf_positive == Approx(1.0002).epsilon(1e-12));
  CHECK(p.sf_negative == Approx(0.9998).epsilon(1e-12));
  CHECK(p.asymmetry_ppm == Approx(400.0).epsilon(1e-6));
  CHECK(p.bias_dph == Approx(7.2).epsilon(1e-9));
}

TEST_CASE("scale factor: the temperature sensitivity and the quadratic model form from five plateaus", "[scale_factor]") {
  // SF(T) = 1.00005 (1 + 30e-6 dT + 0.1e-6 dT^2), dT = T - 20 at -40, -10, 20, 50, 80 degC
  // (dT symmetric about 0, so the linear fit's slope is k1 exactly: sum dT^3 = 0), held (no rate term).
  auto law = [](double r, double t, double) {
    const double d = t - 20.0;
    return 1.00005 * (1.0 + 30e-6 * d + 0.1e-6 * d * d) * r;
  };
  auto rec = make({{1, -40.0, 0.0}, {2, -10.0, 0.0}, {3, 20.0, 0.0}, {4, 50.0, 0.0}, {5, 80.0, 0.0}}, kRates, 10, law);
  auto res = sf::fit(rec);
  REQUIRE(res);
  REQUIRE(res->tc_ppm_per_c.value);
  // The linear fit's constant is the mean of 1 + 0.1e-6 dT^2 (1800 degC^2 on average), so the
  // slope relative to it is 30 / (1 + 1.8e-4) ppm/degC.
  CHECK(*res->tc_ppm_per_c.value == Approx(30.0 / (1.0 + 1.8e-4)).epsilon(1e-7));
  CHECK(res->tc_ppm_per_c.se > 0.0);
  REQUIRE(res->k1_ppm_per_c.value);
  REQUIRE(res->k2_ppm_per_c2.value);
  CHECK(*res->k1_ppm_per_c.value == Approx(30.0).epsilon(1e-7));
  CHECK(*res->k2_ppm_per_c2.value == Approx(0.1).epsilon(1e-6));
  CHECK(res->model_sf0 == Approx(1.00005).epsilon(1e-12));
  CHECK(res->model_rms_ppm < 1e-4);
  CHECK(sf::model_scale_factor(*res, 50.0) == Approx(1.00005 * (1.0 + 30e-6 * 30.0 + 0.1e-6 * 900.0)).epsilon(1e-12));
  // All plateaus held: the temperature rate term is not identified, and says why.
  CHECK_FALSE(res->temp_rate_ppm_per_c_per_min.value);
  CHECK_THAT(res->temp_rate_ppm_per_c_per_min.not_identified, Contains("temperature rates span"));
}

TEST_CASE("scale factor: the temperature rate term from plateaus on ramps", "[scale_factor]") {
  // SF = 1 + 25e-6 (T - 20) + 40e-6 Tdot (Tdot in degC/min), T the instantaneous coil
  // temperature. With the rates symmetric (mean 0) the plateau's slope is SF at the
  // (r^2-weighted) mean coil temperature of its steps, which fit() reports as the plateau's
  // temperature: the across-plateau regression recovers 25 ppm/degC and 40 ppm per degC/min.
  auto law = [](double r, double t, double tdot) { return (1.0 + 25e-6 * (t - 20.0) + 40e-6 * tdot) * r; };
  auto rec = make({{1, -20.0, 0.0}, {2, 0.0, 0.5}, {3, 20.0, 0.0}, {4, 40.0, -0.5}, {5, 60.0, 0.0}, {6, 20.0, 1.0}}, kRates, 20, law);
  auto res = sf::fit(rec);
  REQUIRE(res);
  CHECK(res->plateaus[1].temp_rate_c_per_min == Approx(0.5).epsilon(1e-9));
  REQUIRE(res->tc_ppm_per_c.value);
  REQUIRE(res->temp_rate_ppm_per_c_per_min.value);
  CHECK(*res->tc_ppm_per_c.value == Approx(25.0).epsilon(1e-6));
  CHECK(*res->temp_rate_ppm_per_c_per_min.value == Approx(40.0).epsilon(1e-6));
  CHECK(res->sf0 == Approx(1.0).epsilon(1e-12));
}

TEST_CASE("scale factor: bad input is an error naming the plateau and step", "[scale_factor]") {
  auto linear = [](double r, double, double) { return r; };
  SECTION("a plateau with a single rate") {
    auto rec = make({{7, 20.0, 0.0}}, {50.0, 50.0}, 10, linear);
    auto res = sf::fit(rec);
    REQUIRE_FALSE(res);
    CHECK_THAT(res.error(), Contains("plateau 7") && Contains("single input rate"));
  }
  SECTION("no negative rate, so no asymmetry") {
    auto rec = make({{2, 20.0, 0.0}}, {0.0, 10.0, 100.0}, 10, linear);
    auto res = sf::fit(rec);
    REQUIRE_FALSE(res);
    CHECK_THAT(res.error(), Contains("plateau 2") && Contains("no negative input rate"));
  }
  SECTION("a step with no sample after settling") {
    auto rec = make({{4, 20.0, 0.0}}, kRates, 10, linear);
    sf::Options o;
    o.settle_s = 10.0;
    auto res = sf::fit(rec, o);
    REQUIRE_FALSE(res);
    CHECK_THAT(res.error(), Contains("plateau 4, step 0") && Contains("no sample left"));
  }
  SECTION("a NaN output") {
    auto rec = make({{1, 20.0, 0.0}}, kRates, 10, linear);
    rec.rate_out_dps[23] = std::nan("");
    auto res = sf::fit(rec);
    REQUIRE_FALSE(res);
    CHECK_THAT(res.error(), Contains("plateau 1, row 23") && Contains("rate_out_dps"));
  }
  SECTION("a plateau seen again after another") {
    auto rec = make({{1, 20.0, 0.0}, {2, 30.0, 0.0}, {1, 20.0, 0.0}}, kRates, 10, linear);
    for (std::size_t i = 0; i < rec.time_s.size(); ++i) rec.time_s[i] = static_cast<double>(i);
    auto res = sf::fit(rec);
    REQUIRE_FALSE(res);
    CHECK_THAT(res.error(), Contains("plateau 1, row 100") && Contains("again"));
  }
  SECTION("columns of different lengths, and no samples") {
    auto rec = make({{1, 20.0, 0.0}}, kRates, 10, linear);
    rec.coil_c.pop_back();
    CHECK_THAT(sf::fit(rec).error(), Contains("different lengths"));
    CHECK_THAT(sf::fit(sf::RateRecord{}).error(), Contains("no samples"));
  }
  SECTION("an invalid option") {
    sf::Options o;
    o.settle_s = -1.0;
    CHECK_THAT(sf::fit(make({{1, 20.0, 0.0}}, kRates, 10, linear), o).error(), Contains("settle_s"));
  }
}

// A stored run (RunData) as the daemon exports it: the ramp between two holds and the settle
// phase are left out, flagged samples dropped, and the record fits as the CSV of the same rows.
TEST_CASE("scale factor rate_record: a stored run's turning plateaus, flagged and settle samples left out", "[scale_factor]") {
  namespace m = fogbench::model;
  m::RunData run;
  run.name = "run 7";
  double t = 0.0;
  auto add = [&](int step, m::Phase ph, double rate, double coil, std::uint8_t flags) {
    run.time_s.push_back(t);
    t += 1.0;
    run.step.push_back(step);
    run.phase.push_back(ph);
    run.rate_in_dps.push_back(rate);
    // sf = 1 + 10 ppm/degC (coil - 20); bias 36 deg/h (0.01 deg/s)
    run.gyro_dph.push_back(3600.0 * (0.01 + (1.0 + 10e-6 * (coil - 20.0)) * rate));
    run.t1_c.push_back(coil);
    run.t2_c.push_back(coil);
    run.flags.push_back(flags);
  };
  for (int k = 0; k < 5; ++k) add(0, m::Phase::settle, 0.0, 20.0, 0);
  for (double rate : {10.0, -10.0, 100.0, -100.0, 0.0})
    for (int k = 0; k < 10; ++k) add(0, m::Phase::hold, rate, 20.0, 0);
  for (int k = 0; k < 20; ++k) add(1, m::Phase::heating, 0.0, 20.0 + k, 0);
  for (double rate : {10.0, -10.0, 100.0, -100.0, 0.0})
    for (int k = 0; k < 10; ++k) add(2, m::Phase::hold, rate, 40.0, k == 7 ? m::flag::missing : 0);
  run.gyro_dph[run.size() - 2] = std::nan("");  // not read, flagged: left out, not a fit error
  run.flags[run.size() - 2] = m::flag::missing;
  for (int k = 0; k < 10; ++k) add(3, m::Phase::cooling, 0.0, 40.0 - k, 0);
  for (double rate : {10.0, -10.0, 100.0, -100.0, 0.0})
    for (int k = 0; k < 10; ++k) add(4, m::Phase::hold, rate, 30.0, 0);
  auto rec = sf::rate_record(run);
  REQUIRE(rec.has_value());
  CHECK(rec->size() == 50 + 50 - 6 + 50);  // settle and ramps out, 5 flagged rows + the NaN one
  CHECK(rec->plateau.front() == 0);
  CHECK(rec->plateau.back() == 4);
  auto f = sf::fit(*rec, {});
  REQUIRE(f.has_value());
  REQUIRE(f->plateaus.size() == 3);
  REQUIRE(f->tc_ppm_per_c.value);
  CHECK(*f->tc_ppm_per_c.value == Approx(10.0).margin(1e-6));

  SECTION("no rate table, or a table at rest throughout: the reason, never a value") {
    m::RunData rest = run;
    for (auto& r : rest.rate_in_dps) r = 0.0;
    auto e = sf::rate_record(rest);
    REQUIRE_FALSE(e.has_value());
    CHECK_THAT(e.error(), Contains("no profile step in which the rate table turned"));
    rest.rate_in_dps.clear();
    e = sf::rate_record(rest);
    REQUIRE_FALSE(e.has_value());
    CHECK_THAT(e.error(), Contains("drove no rate table"));
  }
}
