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

namespace {

// A bench run with a recorded setpoint: a 600 s hold at 20 degC, a ramp of 10 degC at
// rate_c_per_min, a 1800 s hold, the ramp back and a 1200 s hold. The air follows the setpoint
// by a first-order lag of 43 s, the outer wall (T2) the air by tau_wall_s, the coil's centre
// (T1) the wall by tau_core_s (Euler steps of 0.1 s); every thermistor rounded to resolution_c,
// no noise: the longest a real thermistor can stay put.
RunData lagged_bench(double rate_c_per_min, double tau_wall_s, double tau_core_s, double resolution_c) {
  const double ramp_s = 10.0 / rate_c_per_min * 60.0;
  const double n_s = 600 + ramp_s + 1800 + ramp_s + 1200;
  auto sp = [&](double t) {
    if (t < 600) return 20.0;
    if (t < 600 + ramp_s) return 20.0 + (t - 600) * rate_c_per_min / 60;
    if (t < 2400 + ramp_s) return 30.0;
    if (t < 2400 + 2 * ramp_s) return 30.0 - (t - 2400 - ramp_s) * rate_c_per_min / 60;
    return 20.0;
  };
  auto q = [&](double v) { return std::round(v / resolution_c) * resolution_c; };
  RunData r;
  r.name = "lagged bench";
  double ta = 20, t2 = 20, t1 = 20;
  for (std::size_t i = 0; static_cast<double>(i) < n_s; ++i) {
    const double t = static_cast<double>(i);
    r.time_s.push_back(t);
    r.setpoint_c.push_back(sp(t));
    r.chamber_c.push_back(q(ta));
    r.t2_c.push_back(q(t2));
    r.t1_c.push_back(q(t1));
    r.gyro_dph.push_back(-8.0);
    for (int s = 0; s < 10; ++s) {
      const double u = t + 0.1 * s;
      ta += 0.1 * (sp(u) - ta) / 43.0;
      t2 += 0.1 * (ta - t2) / tau_wall_s;
      t1 += 0.1 * (t2 - t1) / tau_core_s;
    }
  }
  return r;
}

std::vector<QualityFlag> stuck_flags(const QualityReport& q, const std::string& sensor) {
  std::vector<QualityFlag> out;
  for (const auto& f : q.flags)
    if (f.kind == QualityKind::stuck && f.sensor == sensor) out.push_back(f);
  return out;
}

std::string all_messages(const QualityReport& q) {
  std::string s;
  for (const auto& f : q.flags) s += f.message() + "\n";
  return s;
}

// The longest run of exact repeats of x, s.
double longest_repeat_s(const std::vector<double>& x) {
  std::size_t best = 0, cur = 1;
  for (std::size_t i = 1; i < x.size(); ++i) {
    cur = x[i] == x[i - 1] ? cur + 1 : 1;
    best = std::max(best, cur);
  }
  return static_cast<double>(best);
}

struct Coil {
  const char* name;
  double tau_wall_s, tau_core_s;
};
// The mock bench's coil (its centre 68 s at 20.00 degC at a ramp's start, last session's false
// alarm), and a big coil whose centre lags the air by 3..5 min.
constexpr Coil kLaggedCoils[] = {{"mock", 105, 38}, {"big", 150, 120}, {"big, slow centre", 120, 180}};

}  // namespace

TEST_CASE("quality: a coil's centre lagging the air at a ramp's start is not stuck", "[quality][stuck]") {
  for (const auto& coil : kLaggedCoils)
    for (double rate : {2.0, 1.0, 0.2})
      for (double res : {0.01, 0.1}) {
        const auto r = lagged_bench(rate, coil.tau_wall_s, coil.tau_core_s, res);
        INFO(coil.name << " coil, " << rate << " degC/min, resolution " << res << " degC");
        // The case is real: the centre stays put a minute or more after the air moved.
        if (res == 0.01 && rate == 1.0) CHECK(longest_repeat_s(r.t1_c) >= 60);
        const auto q = assess_quality(r);
        INFO(all_messages(q));
        CHECK(stuck_flags(q, "T1").empty());
        CHECK(stuck_flags(q, "T2").empty());
        CHECK(stuck_flags(q, "Ta").empty());
      }
}

TEST_CASE("quality: a thermistor truly stuck is still named, mid-ramp, over a whole ramp, from a ramp's start", "[quality][stuck]") {
  for (const auto& coil : kLaggedCoils)
    for (const std::string sensor : {"T1", "T2"}) {
      INFO(coil.name << " coil, " << sensor);
      auto col = [&](RunData& r) -> std::vector<double>& { return sensor == "T1" ? r.t1_c : r.t2_c; };
      {
        // Frozen 5 min in the middle of a 10 min ramp at 1 degC/min (600..1200 s).
        auto r = lagged_bench(1.0, coil.tau_wall_s, coil.tau_core_s, 0.01);
        for (std::size_t i = 900; i < 1200; ++i) col(r)[i] = col(r)[900];
        const auto q = assess_quality(r);
        INFO(all_messages(q));
        const auto f = stuck_flags(q, sensor);
        REQUIRE(f.size() == 1);
        CHECK(f[0].start_s <= 900);
        CHECK(f[0].end_s >= 1199);
      }
      {
        // Frozen from the ramp's start to 10 minutes after its end.
        auto r = lagged_bench(1.0, coil.tau_wall_s, coil.tau_core_s, 0.01);
        for (std::size_t i = 600; i < 1800; ++i) col(r)[i] = col(r)[600];
        const auto q = assess_quality(r);
        INFO(all_messages(q));
        const auto f = stuck_flags(q, sensor);
        REQUIRE(f.size() == 1);
        CHECK(f[0].start_s <= 600);
        CHECK(f[0].end_s >= 1799);
      }
      {
        // Frozen over the hold that follows the ramp, 10 min after the coil settled: nothing
        // moves, no evidence of sticking, no flag (a sensor still during a hold is not stuck).
        auto r = lagged_bench(1.0, coil.tau_wall_s, coil.tau_core_s, 0.01);
        for (std::size_t i = 2700; i < 3000; ++i) col(r)[i] = col(r)[2700];
        const auto q = assess_quality(r);
        INFO(all_messages(q));
        CHECK(stuck_flags(q, sensor).empty());
      }
    }
  // The mock coil frozen for 8 min from the ramp's start while its wall and the air move by degrees.
  auto r = lagged_bench(1.0, 105, 38, 0.01);
  for (std::size_t i = 600; i < 1080; ++i) r.t1_c[i] = 20.0;
  const auto q = assess_quality(r);
  INFO(all_messages(q));
  REQUIRE(stuck_flags(q, "T1").size() == 1);
}

TEST_CASE("quality: without a recorded setpoint, or without the air too, lagging coils raise no stuck flag and a frozen one is named",
          "[quality][stuck]") {
  // The stuck check's witnesses when the run has no setpoint: T1 is judged against T2 and the
  // air, T2 against the air, the air against the coil's thermistors looked at later; with
  // neither setpoint nor air, T1 against T2 and T2 against T1 looked at later
  // (docs/data-quality.md, "The stuck check").
  enum class Recorded { air, neither };
  for (const auto recorded : {Recorded::air, Recorded::neither})
    for (const auto& coil : kLaggedCoils) {
      const char* what = recorded == Recorded::air ? "no setpoint" : "no setpoint, no air";
      auto strip = [&](RunData r) {
        r.setpoint_c.clear();
        if (recorded == Recorded::neither) r.chamber_c.clear();
        return r;
      };
      for (double rate : {2.0, 1.0, 0.2}) {
        const auto r = strip(lagged_bench(rate, coil.tau_wall_s, coil.tau_core_s, 0.01));
        INFO(what << ", " << coil.name << " coil, " << rate << " degC/min");
        const auto q = assess_quality(r);
        INFO(all_messages(q));
        CHECK(stuck_flags(q, "T1").empty());
        CHECK(stuck_flags(q, "T2").empty());
        CHECK(stuck_flags(q, "Ta").empty());
      }
      std::vector<std::string> sensors{"T1", "T2"};
      if (recorded == Recorded::air) sensors.push_back("Ta");
      for (const auto& sensor : sensors) {
        // Frozen 5 min in the middle of the 10 min ramp at 1 degC/min (600..1200 s).
        auto r = strip(lagged_bench(1.0, coil.tau_wall_s, coil.tau_core_s, 0.01));
        auto& x = sensor == "T1" ? r.t1_c : sensor == "T2" ? r.t2_c : r.chamber_c;
        for (std::size_t i = 900; i < 1200; ++i) x[i] = x[900];
        INFO(what << ", " << coil.name << " coil, " << sensor << " frozen mid-ramp");
        const auto q = assess_quality(r);
        INFO(all_messages(q));
        const auto f = stuck_flags(q, sensor);
        REQUIRE(f.size() == 1);
        CHECK(f[0].start_s <= 900);
        CHECK(f[0].end_s >= 1199);
      }
    }
}
