// The data-quality check's contract on small synthetic runs whose every figure is known:
// options validated by name, tiny runs judged without failing, each flag's interval exact,
// cleaning flags exactly the flagged samples, and the identification warnings.
#include <catch2/catch.hpp>
#include <cmath>
#include <random>

#include "fogbench/model/model.hpp"
#include "fogbench/model/quality.hpp"

using namespace fogbench::model;
using Catch::Contains;

namespace {

// n seconds: a 600 s hold at 20 degC, then a triangle of +-5 degC at 1 degC/min; T2 leads T1
// by 40 s (the wall ahead of the centre), Ta leads T2 by 120 s; thermistors with 0.005 degC
// of white noise, the gyro -8 deg/h with 0.15 deg/h of white noise.
RunData synthetic(std::size_t n, unsigned seed) {
  RunData r;
  r.name = "synthetic";
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> tn(0.0, 0.005), gn(0.0, 0.15);
  auto tri = [](double t) {
    if (t < 600) return 20.0;
    const double u = std::fmod(t - 600, 1200.0);  // 1 degC/min: 5 degC in 300 s, a cycle of 1200 s
    const double v = u < 300 ? u / 60 : u < 900 ? 5 - (u - 300) / 60 : -5 + (u - 900) / 60;
    return 20.0 + v;
  };
  for (std::size_t i = 0; i < n; ++i) {
    const double t = static_cast<double>(i);
    r.time_s.push_back(t);
    r.t1_c.push_back(tri(t - 160) + tn(rng));
    r.t2_c.push_back(tri(t - 120) + tn(rng));
    r.chamber_c.push_back(tri(t) + tn(rng));
    r.gyro_dph.push_back(-8.0 + gn(rng));
  }
  return r;
}

}  // namespace

TEST_CASE("quality options: each constraint named", "[quality]") {
  CHECK(QualityOptions{}.validate());
  QualityOptions o;
  o.min_temp_c = 200;
  CHECK_THAT(o.validate().error(), Contains("min_temp_c"));
  o = {};
  o.spike_sigma = 0;
  CHECK_THAT(o.validate().error(), Contains("spike_sigma"));
  o = {};
  o.max_lag_scan_s = 100;  // under the wall's bound of 360 s: a lag beyond it would never be seen
  CHECK_THAT(o.validate().error(), Contains("max_lag_scan_s"));
}

TEST_CASE("quality: tiny and empty runs are judged without failing", "[quality]") {
  for (std::size_t n : {0u, 1u, 2u, 3u, 5u, 40u}) {
    RunData r = synthetic(n, 1);
    const auto q = assess_quality(r);
    CHECK(q.ok());
  }
}

TEST_CASE("quality: the synthetic run is clean, its lags are the ones built in", "[quality]") {
  const auto q = assess_quality(synthetic(6000, 2));
  INFO((q.flags.empty() ? std::string() : q.flags[0].message()));
  CHECK(q.ok());
  // Pure delays of 40 s (T1 behind T2) and 120 s (T2 behind Ta): the rates' cross-correlation
  // peaks there, within a second.
  CHECK(q.core_lag_s == Approx(40).margin(1));
  CHECK(q.wall_lag_s == Approx(120).margin(1));
  CHECK(q.t1_noise_c == Approx(0.005).epsilon(0.2));
}

TEST_CASE("quality: cleaning flags exactly the flagged samples, by default only the safe ones", "[quality]") {
  RunData r = synthetic(6000, 3);
  for (std::size_t i = 1000; i < 1030; ++i) r.t2_c[i] = std::nan("");  // 30 s dropout: bridged by default
  for (std::size_t i = 2000; i < 2200; ++i) r.t1_c[i] = 150.0;        // 200 s out of range: on request
  r.gyro_dph[4000] = 1e6;                                             // an isolated spike: by default
  const auto q = assess_quality(r);
  REQUIRE(q.flags.size() == 3);
  const auto d = clean_run(r, q, CleanPolicy::by_default);
  CHECK(d.cleaned.size() == 2);
  REQUIRE(d.remaining.size() == 1);
  CHECK(d.remaining[0].sensor == "T1");
  CHECK(d.remaining[0].kind == QualityKind::out_of_range);
  std::size_t flagged = 0;
  for (std::size_t i = 0; i < r.size(); ++i) flagged += d.run.flags[i] != 0;
  CHECK(flagged == 31);  // 30 dropout samples + 1 spike
  CHECK(d.run.flags[1000] == flag::missing);
  CHECK(d.run.flags[4000] == flag::out_of_range);
  const auto a = clean_run(r, q, CleanPolicy::all);
  CHECK(a.remaining.empty());
  flagged = 0;
  for (std::size_t i = 0; i < r.size(); ++i) flagged += a.run.flags[i] != 0;
  CHECK(flagged == 231);
  // The values are left as they were: only the flags say what to skip.
  CHECK(a.run.t1_c[2000] == 150.0);
  CHECK(assess_quality(a.run).ok());
}

TEST_CASE("quality: a sensor lost over most of the run cannot be cleaned", "[quality]") {
  RunData r = synthetic(3000, 4);
  for (std::size_t i = 0; i < 2000; ++i) r.t2_c[i] = -273.15;
  const auto q = assess_quality(r);
  REQUIRE(q.flags.size() == 1);
  CHECK_FALSE(q.flags[0].cleanable);
  CHECK_THAT(q.flags[0].remedy, Contains("cannot be fitted"));
  CHECK(clean_run(r, q, CleanPolicy::all).remaining.size() == 1);
}

TEST_CASE("quality: identification warnings of a fit", "[quality]") {
  // A coefficient whose se exceeds its value is named; a fit with |coef| > se is not.
  Model m;
  m.max_lag_s = 600;
  FittedTerm t;
  t.term = *parse_term("T1");
  t.coef = 0.01;
  t.se_dph_per_unit = 0.02;
  m.terms.push_back(t);
  const RunData r = synthetic(6000, 5);
  auto w = identification_warnings(m, r);
  REQUIRE(w.size() == 1);
  CHECK_THAT(w[0], Contains("T1") && Contains("exceeds its value"));
  m.terms[0].coef = 0.05;
  CHECK(identification_warnings(m, r).empty());
  // A hold only: no excitation.
  RunData hold = synthetic(590, 6);
  CHECK_THAT(identification_warnings(m, hold).at(0), Contains("no temperature excitation"));
  // Ramps shorter than the lag range with an @auto lag: 600 s of hold + 400 s of ramp.
  m.terms[0].term = *parse_term("T1@auto");
  RunData short_run = synthetic(1000, 7);
  w = identification_warnings(m, short_run);
  REQUIRE_FALSE(w.empty());
  CHECK_THAT(w.back(), Contains("too short for the lag range"));
}
