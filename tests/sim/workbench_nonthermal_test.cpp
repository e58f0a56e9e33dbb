// Drift that is not thermal (issue 25 point 3): an ageing ramp with no power-on column is named
// as a drift in time (not a temperature term), a periodic disturbance is named with its period
// and amplitude, and clean runs with realistic FOG noise raise neither.
#include <catch2/catch.hpp>
#include <cmath>
#include <string>

#include "fogbench/model/model.hpp"
#include "fogbench/model/workbench.hpp"
#include "fogbench/sim/sim.hpp"
#include "programs.hpp"

using namespace fogbench;
namespace wb = model::workbench;

namespace {

using fogbench::test::program;

struct Truth {
  double arw = 0.0024, bi = 0.0, rrw = 0.0;   // deg/sqrt(h), deg/h, deg/h/sqrt(h)
  double ageing_dph_per_h = 0.0;
  double period_s = 0.0, amplitude_dph = 0.0, phase_rad = 0.0;
  bool distributed = false;  // the radial-layer coil (the paper's model then misfits a little)
};

model::RunData run(const std::string& profile, std::uint64_t seed, const Truth& tr) {
  sim::SimConfig cfg;
  cfg.seed = seed;
  auto& u = cfg.units[0];
  // The lumped coil: the paper's model is the exact thermal truth.
  u.coil.model = tr.distributed ? sim::CoilModel::distributed : sim::CoilModel::lumped;
  u.gyro.sigma_a_dph = 60.0 * tr.arw;
  u.gyro.bias_instability_dph = tr.bi;
  u.gyro.rrw_dph_per_sqrt_h = tr.rrw;
  u.gyro.ageing_dph_per_h = tr.ageing_dph_per_h;
  u.gyro.periodic_period_s = tr.period_s;
  u.gyro.periodic_amplitude_dph = tr.amplitude_dph;
  u.gyro.periodic_phase_rad = tr.phase_rad;
  auto r = sim::simulate(cfg, program(profile));
  REQUIRE(r);
  model::RunData d = r->front();
  d.name = profile;
  return d;
}

std::vector<model::RunData> runs(std::uint64_t seed, const Truth& tr) {
  return {run("exp1", seed, tr), run("exp2", seed + 1, tr), run("exp3", seed + 2, tr)};
}

std::expected<wb::Diagnosis, model::FitError> diagnose(const std::vector<model::RunData>& r) {
  auto m = model::fit(r[0], *model::parse_terms("paper"));
  REQUIRE(m);
  return wb::diagnose(*m, r[0], std::span<const model::RunData>(r).subspan(1));
}

}  // namespace

TEST_CASE("sim: the ageing ramp and the periodic disturbance are off by default and exact when on", "[sim][nonthermal]") {
  const Truth none;
  Truth on;
  on.ageing_dph_per_h = 0.02;
  on.period_s = 1200.0;
  on.amplitude_dph = 0.3;
  const auto a = run("exp1", 7, none), b = run("exp1", 7, on);
  REQUIRE(a.size() == b.size());
  // The same noise realisation: the difference is exactly the non-thermal drift.
  for (std::size_t i : {std::size_t{0}, std::size_t{300}, std::size_t{5000}, a.size() - 1}) {
    const double t = static_cast<double>(i);
    CHECK(b.gyro_dph[i] - a.gyro_dph[i] == Approx(0.02 * t / 3600.0 + 0.3 * std::sin(2.0 * 3.141592653589793 * t / 1200.0)).margin(1e-9));
  }
  CHECK_FALSE(b.has_power_on());
}

TEST_CASE("term language: trun is the run's own clock in hours", "[nonthermal]") {
  auto t = model::parse_term("trun");
  REQUIRE(t);
  CHECK(model::to_string(*t->expr) == "trun");
  CHECK(model::coef_unit(*t->expr) == "deg/h per h");
  std::vector<double> z(7201, 0.0);
  model::Signals s{z, z, {}, 1.0};
  auto v = model::evaluate(*t->expr, s);
  REQUIRE(v);
  CHECK((*v)[3600] == Approx(1.0));
  CHECK((*v)[7200] == Approx(2.0));
}

TEST_CASE("workbench: an ageing ramp with no power-on column is named as a drift in time, not thermal", "[nonthermal][sim]") {
  // Near the noise floor (0.02 deg/h per h: 0.06 deg/h over a 3 h run against a noise std of
  // 0.15 deg/h) and well above it (0.1), on a gyro with a rate random walk as well.
  struct Case {
    double slope;
    Truth noise;
  };
  Truth white;
  Truth slow;
  slow.bi = 0.02;
  slow.rrw = 0.02;
  const Case cases[] = {{0.02, white}, {0.1, white}, {0.1, slow}, {-0.08, slow}};
  int named = 0, total = 0;
  std::string why;
  std::uint64_t seed = 2100;
  for (const auto& c : cases)
    for (int k = 0; k < 3; ++k, seed += 10) {
      Truth tr = c.noise;
      tr.ageing_dph_per_h = c.slope;
      auto d = diagnose(runs(seed, tr));
      REQUIRE(d);
      ++total;
      const auto& td = d->time_drift;
      // The run's clock has no delay to find (trun delayed is trun less a constant): added at lag 0.
      const bool ok = td.found && td.named && !d->steps.empty() && d->steps.front().expr == "trun" &&
                      (d->steps.front().added == "trun" || d->steps.front().added == "trun@0") &&
                      d->summary.rfind("Missing effect: a drift in time", 0) == 0 &&
                      std::abs(td.slope_dph_per_h - c.slope) <= 3.0 * td.se_dph_per_h + 0.1 * std::abs(c.slope);
      if (ok) ++named;
      else {
        why += "slope " + std::to_string(c.slope) + " seed " + std::to_string(seed) + ": " + d->summary +
               (d->steps.empty() ? std::string() : " (first step added " + d->steps.front().added + ")") + "\n";
        for (const auto& x : d->candidates)
          if (x.expr == "trun") {
            why += "  trun: " + x.verdict + " fall " + std::to_string(x.fall) + " p " + std::to_string(x.p_value);
            for (const auto& h : x.held_out) why += " " + h.run + " " + std::to_string(h.rms_before_dph) + "->" + std::to_string(h.rms_after_dph);
            why += "\n";
          }
      }
    }
  INFO(why);
  // At most 2 of 12 missed (1 before branch ntfloor): each run's slope is now judged against the
  // slow noise the whole run's Allan curve shows at its best fit even where the floor keeps no
  // slow law (issue 25 point 1: t 5 to 18 on clean ARW 0.01 runs with a hidden flicker or walk).
  // The two it misses: seed 2110, 0.02 deg/h per h on white noise (t 4.8: the best fit reads a
  // walk of 0.007 deg/h/sqrt(h) on the last octaves), and seed 2160, 0.1 under B 0.02, K 0.02,
  // whose walk left exp2 a slope of +0.008 (t 2.8).
  CHECK(named >= total - 2);
}

TEST_CASE("workbench: a periodic disturbance is named with its period and amplitude", "[nonthermal][sim]") {
  // Periods of 900 to 3000 s, amplitudes near the noise (0.1 deg/h, below the noise std) and
  // well above it (0.5 deg/h).
  struct Case {
    double period_s, amplitude_dph;
  };
  const Case cases[] = {{900.0, 0.1}, {1500.0, 0.5}, {3000.0, 0.3}, {2200.0, 0.15}};
  Truth slow;
  slow.bi = 0.02;
  int named = 0, total = 0;
  std::string why;
  std::uint64_t seed = 3100;
  for (const auto& c : cases)
    for (int k = 0; k < 2; ++k, seed += 10) {
      Truth tr = k == 0 ? Truth{} : slow;
      tr.period_s = c.period_s;
      tr.amplitude_dph = c.amplitude_dph;
      tr.phase_rad = 0.7 * static_cast<double>(seed % 7);
      auto d = diagnose(runs(seed, tr));
      REQUIRE(d);
      ++total;
      bool ok = !d->periodic.empty() && !d->adequate;
      for (const auto& p : d->periodic) {
        ok = ok && std::abs(p.period_s - c.period_s) <= 0.1 * c.period_s && std::abs(p.amplitude_dph - c.amplitude_dph) <= 0.3 * c.amplitude_dph;
        ok = ok && p.message.find("period") != std::string::npos;
      }
      // No thermal term is invented for it.
      ok = ok && d->steps.empty();
      if (ok) ++named;
      else {
        why += "period " + std::to_string(c.period_s) + " amplitude " + std::to_string(c.amplitude_dph) + " seed " + std::to_string(seed) + ":";
        for (const auto& p : d->periodic) why += " [" + std::to_string(p.period_s) + " s " + std::to_string(p.amplitude_dph) + " deg/h]";
        why += " " + d->summary + "\n";
      }
    }
  INFO(why);
  CHECK(named >= total - 1);
}

TEST_CASE("workbench: clean runs with realistic FOG noise show no drift in time and no periodic disturbance", "[nonthermal][sim]") {
  const Truth cases[] = {{0.001, 0.0, 0.1}, {0.001, 0.05, 0.0}, {0.01, 0.05, 0.1}, {0.0024, 0.0, 0.0}};
  int alarms = 0, total = 0;
  std::string why;
  std::uint64_t seed = 4100;
  for (const auto& tr : cases)
    for (int k = 0; k < 3; ++k, seed += 10) {
      auto d = diagnose(runs(seed, tr));
      REQUIRE(d);
      ++total;
      if (d->time_drift.found || !d->periodic.empty()) {
        ++alarms;
        why += "seed " + std::to_string(seed) + ": " + d->summary + "\n";
      }
    }
  INFO(why);
  CHECK(alarms <= 1);
}


TEST_CASE("workbench: a periodic disturbance on the held-out run only is named over a rate random walk", "[nonthermal][sim]") {
  // The fit run (exp1) is clean; the held-out run (exp3, 9300 s) carries the line. The gyro
  // has the slow noise (ARW 0.001 deg/sqrt(h), RRW 0.1 deg/h/sqrt(h)) on the
  // distributed coil. The whole run's Allan curve reads the line's bump as a random walk, and
  // against that floor (rising as 1/f^2 below the line) the line sank under a noise ordinate
  // at a short period: the model was called adequate. Amplitudes of 0.15 to 0.3 deg/h, 1 to 2
  // times the run's noise std at the line's period and below the residual's std (0.2 to 0.3
  // deg/h). Seeds from a screen of 36 (6 periods x 6 seeds): main missed 5 (the 5 below with
  // a "missed" mark) and named the other 31, the other 2 here among them.
  struct Case {
    double period_s, amplitude_dph;
    std::uint64_t seed;
  };
  const Case cases[] = {{1800.0, 0.3, 5100},  {1800.0, 0.3, 5140} /* missed */, {900.0, 0.15, 5160} /* missed */,
                        {2700.0, 0.3, 5230} /* missed */, {2700.0, 0.3, 5240} /* missed */,
                        {1200.0, 0.2, 5300} /* missed */, {600.0, 0.15, 5400}};
  Truth clean;
  clean.arw = 0.001;
  clean.rrw = 0.1;
  clean.distributed = true;
  int named = 0, total = 0;
  std::string why;
  for (const auto& c : cases) {
    Truth tr = clean;
    tr.period_s = c.period_s;
    tr.amplitude_dph = c.amplitude_dph;
    tr.phase_rad = 0.9 * static_cast<double>(c.seed % 5);
    const std::vector<model::RunData> r = {run("exp1", c.seed, clean), run("exp3", c.seed + 1, tr)};
    auto d = diagnose(r);
    REQUIRE(d);
    ++total;
    // Named on exp3 alone, within 10 % in period and 30 % in amplitude, and not adequate.
    bool ok = !d->adequate && d->periodic.size() == 1;
    for (const auto& p : d->periodic)
      ok = ok && p.run == "exp3" && std::abs(p.period_s - c.period_s) <= 0.1 * c.period_s &&
           std::abs(p.amplitude_dph - c.amplitude_dph) <= 0.3 * c.amplitude_dph;
    if (ok) ++named;
    else {
      why += "period " + std::to_string(c.period_s) + " amplitude " + std::to_string(c.amplitude_dph) + " seed " + std::to_string(c.seed) + ":";
      for (const auto& p : d->periodic) why += " [" + p.run + " " + std::to_string(p.period_s) + " s " + std::to_string(p.amplitude_dph) + " deg/h]";
      why += " " + d->summary.substr(0, 200) + "\n";
    }
  }
  // Clean pairs (no line) raise no periodic disturbance, on either coil: on the lumped coil
  // the walk's lowest ordinates, taken for a line and removed, lower the walk the floor reads.
  int alarms = 0;
  for (std::uint64_t seed : {5500u, 5510u, 5540u, 5550u}) {
    Truth c0 = clean;
    c0.distributed = seed < 5540u;
    const std::vector<model::RunData> r = {run("exp1", seed, c0), run("exp3", seed + 1, c0)};
    auto d = diagnose(r);
    REQUIRE(d);
    if (!d->periodic.empty()) {
      ++alarms;
      why += "clean seed " + std::to_string(seed) + ": " + d->periodic.front().message + "\n";
    }
  }
  INFO(why);
  CHECK(named >= total - 1);
  CHECK(alarms <= 1);
}

TEST_CASE("workbench: the periodic search raises no line from a rate random walk alone", "[nonthermal][sim]") {
  // find_periodic on clean runs (lumped coil: the paper's model is exact, the residual is the
  // gyro's noise) with the slow noise, ARW 0.001 deg/sqrt(h) and RRW 0.1
  // deg/h/sqrt(h). Its test is at p 1e-4 over every frequency searched: over 40 runs the
  // chance of even one alarm is under 1 % when the floor is read right. A walk's lowest
  // ordinate taken for a line and removed lowers the walk the floor reads, and then passes.
  Truth clean;
  clean.arw = 0.001;
  clean.rrw = 0.1;
  const model::RunData fit_run = run("exp1", 6000, clean);
  auto m = model::fit(fit_run, *model::parse_terms("paper"));
  REQUIRE(m);
  int alarms = 0;
  std::string why;
  for (std::uint64_t seed = 6001; seed <= 6040; ++seed) {
    const model::RunData r = run(seed % 2 ? "exp3" : "exp1", seed, clean);
    if (auto p = wb::find_periodic(*m, r)) {
      ++alarms;
      why += "seed " + std::to_string(seed) + ": " + p->message.substr(0, 160) + "\n";
    }
  }
  INFO(why);
  CHECK(alarms <= 1);
}

TEST_CASE("workbench: an ageing ramp over a rate random walk is one trun term with the whole slope", "[nonthermal][sim]") {
  // 0.5 deg/h per h on a gyro with ARW 0.001 deg/sqrt(h) and RRW 0.1 deg/h/sqrt(h), the fit
  // run exp1 and exp3 held out: the walk moves each run's slope by about 0.1 deg/h per h. The
  // run's clock has no second path: trun again at another delay is the same column a constant
  // apart, and took part of the slope (the reported slope is trun's own coefficient).
  Truth tr;
  tr.arw = 0.001;
  tr.rrw = 0.1;
  tr.ageing_dph_per_h = 0.5;
  int named = 0, total = 0;
  std::string why;
  for (std::uint64_t seed = 7000; seed < 7060; seed += 10) {
    const std::vector<model::RunData> r = {run("exp1", seed, tr), run("exp3", seed + 1, tr)};
    auto d = diagnose(r);
    REQUIRE(d);
    ++total;
    int truns = 0;
    for (const auto& st : d->steps) truns += st.expr == "trun" ? 1 : 0;
    const auto& td = d->time_drift;
    CHECK(truns <= 1);
    const bool ok = truns == 1 && td.found && td.named && std::abs(td.slope_dph_per_h - 0.5) <= 3.0 * td.se_dph_per_h + 0.05;
    if (ok) ++named;
    else why += "seed " + std::to_string(seed) + ": trun steps " + std::to_string(truns) + ", " + d->summary.substr(0, 220) + "\n";
  }
  INFO(why);
  CHECK(named >= total - 1);
}

TEST_CASE("workbench: slow noise hidden under white noise raises no drift in time or periodic line, and real ones stay found", "[nonthermal][sim]") {
  // Issue 25 point 1: at ARW 0.01 deg/sqrt(h) (0.6 deg/h in 1 s) a flicker of B 0.02 deg/h or a
  // walk of 0.05-0.1 deg/h/sqrt(h) hardly shows on the Allan curve (the floor keeps no slow
  // law), yet over a 1.5-2.6 h run it moves each run's slope and the slow end of the
  // periodogram. Judged against white noise alone, time_drift called "a drift in time" on such
  // clean runs (t 6.8 to 18 on fogctl's grid, docs/workbench.md). Now each detector allows for
  // the slow noise the curve cannot exclude. Lumped coil: the paper's model is exact, the
  // residual is the gyro's noise.
  const Truth noises[] = {{0.01, 0.02, 0.05}, {0.01, 0.0, 0.05}, {0.01, 0.02, 0.1}};
  int alarms = 0, total = 0;
  std::string why;
  for (const auto& tr : noises)
    for (std::uint64_t seed = 8000; seed < 8100; seed += 10) {
      const auto r = runs(seed, tr);
      auto m = model::fit(r[0], *model::parse_terms("paper"));
      REQUIRE(m);
      ++total;
      const wb::TimeDrift td = wb::time_drift(*m, r);
      bool alarm = td.found;
      std::string what = td.found ? td.message : std::string();
      for (const auto& x : r)
        if (auto p = wb::find_periodic(*m, x)) {
          alarm = true;
          what += " " + p->message.substr(0, 120);
        }
      if (alarm) {
        ++alarms;
        why += "B " + std::to_string(tr.bi) + " K " + std::to_string(tr.rrw) + " seed " + std::to_string(seed) + ": " + what + "\n";
      }
    }
  INFO(why);
  CHECK(alarms <= 1);  // of 30

  // Well above that noise, on the slowest mix: ageing of 0.5 deg/h per h on every run is a
  // drift in time with its slope, and a line of 0.3 deg/h at 900 s on exp3 is named.
  Truth slow{0.01, 0.02, 0.1};
  int trends = 0, lines = 0, cases = 0;
  std::string missed;
  for (std::uint64_t seed = 8200; seed < 8240; seed += 10) {
    ++cases;
    Truth ageing = slow;
    ageing.ageing_dph_per_h = 0.5;
    const auto ra = runs(seed, ageing);
    auto ma = model::fit(ra[0], *model::parse_terms("paper"));
    REQUIRE(ma);
    const wb::TimeDrift td = wb::time_drift(*ma, ra);
    if (td.found && std::abs(td.slope_dph_per_h - 0.5) <= 3.0 * td.se_dph_per_h + 0.05) ++trends;
    else missed += "ageing seed " + std::to_string(seed) + ": slope " + std::to_string(td.slope_dph_per_h) + " t " + std::to_string(td.t) + "\n";
    Truth line = slow;
    line.period_s = 900.0;
    line.amplitude_dph = 0.3;
    line.phase_rad = 0.4 * static_cast<double>(seed % 7);
    const auto rl = runs(seed + 1, slow);
    auto ml = model::fit(rl[0], *model::parse_terms("paper"));
    REQUIRE(ml);
    const auto p = wb::find_periodic(*ml, run("exp3", seed + 5, line));
    if (p && std::abs(p->period_s - 900.0) <= 90.0 && std::abs(p->amplitude_dph - 0.3) <= 0.09) ++lines;
    else missed += "line seed " + std::to_string(seed) + ": " + (p ? p->message.substr(0, 120) : std::string("none")) + "\n";
  }
  INFO(missed);
  CHECK(trends == cases);
  CHECK(lines == cases);
}
