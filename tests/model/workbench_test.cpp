// The workbench's pure parts on hand-made runs: the effects library, compare's intervals and
// tables, add_term's errors, lineage order, diagnose on short runs, decimation, JSON.
#include <catch2/catch.hpp>
#include <cmath>
#include <functional>
#include <limits>
#include <random>
#include <set>

#include "fogbench/model/json.hpp"
#include "fogbench/model/workbench.hpp"

using namespace fogbench::model;
namespace wb = fogbench::model::workbench;

namespace {

// A run of n seconds: hold 600 s at 20 degC, ramp down 1 degC/min to 10, hold, ramp up to 30,
// hold. The wall follows the setpoint through 150 s, the centre the wall through 40 s. The gyro
// is -8 deg/h - 3 deg/h per degC/min of d(T1), white noise of 0.146 deg/h, plus `extra`.
RunData make_run(std::size_t n, std::uint64_t seed, const std::function<double(std::size_t, double)>& extra = {}) {
  RunData r;
  r.name = "synthetic " + std::to_string(seed);
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, 0.146);
  double t2 = 20.0, t1 = 20.0;
  for (std::size_t t = 0; t < n; ++t) {
    double sp = 20.0;
    int step = 0;
    Phase ph = Phase::hold;
    if (t >= 600 && t < 1200) { sp = 20.0 - static_cast<double>(t - 600) / 60.0; step = 1; ph = Phase::cooling; }
    else if (t >= 1200 && t < 2400) { sp = 10.0; step = 2; }
    else if (t >= 2400 && t < 3600) { sp = 10.0 + static_cast<double>(t - 2400) / 60.0; step = 3; ph = Phase::heating; }
    else if (t >= 3600) { sp = 30.0; step = 4; }
    t2 += (sp - t2) * (1.0 - std::exp(-1.0 / 150.0));
    t1 += (t2 - t1) * (1.0 - std::exp(-1.0 / 40.0));
    r.time_s.push_back(static_cast<double>(t));
    r.t1_c.push_back(t1);
    r.t2_c.push_back(t2);
    r.setpoint_c.push_back(sp);
    r.step.push_back(step);
    r.phase.push_back(ph);
  }
  const auto rate = derivative_per_min(r.t1_c, 1.0);
  for (std::size_t t = 0; t < n; ++t) r.gyro_dph.push_back(-8.0 - 3.0 * rate[t] + noise(rng) + (extra ? extra(t, r.t1_c[t]) : 0.0));
  return r;
}

Model fit_d(const RunData& r) {
  FitOptions o;
  o.method = Method::joint;
  auto m = fit(r, *parse_terms("d(T1)"), o);
  REQUIRE(m);
  return *m;
}

}  // namespace

TEST_CASE("workbench: the effects library is data in the term language, covering TERMS.md") {
  std::set<std::string> seen;
  for (const auto& e : wb::effects_library()) {
    INFO(e.term);
    auto t = parse_term(e.term);
    REQUIRE(t);
    CHECK_FALSE(t->coef_given);
    CHECK(seen.insert(to_string(*t->expr)).second);  // no entry twice
    CHECK(!e.name.empty());
    CHECK(e.explanation.size() > 40);  // a sentence, not a label
    CHECK(!e.separated_by.empty());
    CHECK(wb::find_effect(to_string(*t->expr)) == &e);
  }
  for (const char* t : {"d(T1)", "grad", "T1", "T1^2", "T2", "d(T2)", "d(grad)", "dd(T1)", "T1*d(T1)", "up(d(T1))",
                        "down(d(T1))", "Ta", "d(Ta)", "lp(T1,300)"})
    CHECK(seen.count(t) == 1);
}

TEST_CASE("workbench: compare finds an injected error, its place, phase and step") {
  const RunData clean = make_run(5000, 1);
  const Model m = fit_d(clean);
  // +1 deg/h for 300 s from t = 1500 s (the hold at 10 degC, step 2).
  const RunData bad = make_run(5000, 2, [](std::size_t t, double) { return t >= 1500 && t < 1800 ? 1.0 : 0.0; });
  auto c = wb::compare(m, bad);
  REQUIRE(c);
  REQUIRE(c->failures.size() == 1);
  const auto& f = c->failures[0];
  // The 61 s average of a 1 deg/h step exceeds 3 sigma_a (0.44 deg/h) once 27 of its 61
  // samples hold it: from 1500 - 30 + 26 = 1496 s to 1800 + 30 - 27 = 1803 s, so the interval
  // starts near 1497 s and lasts about 306 s, give or take a few seconds of noise (the
  // average's own noise is 0.146/sqrt(61) = 0.019 deg/h against a slope of 1/61 deg/h per s).
  CHECK(f.start_s == Approx(1497.0).margin(5.0));
  CHECK(f.duration_s == Approx(306.0).margin(10.0));
  CHECK(f.phase == Phase::hold);
  CHECK(f.step == 2);
  CHECK(f.peak_err_dph == Approx(1.0).margin(0.08));   // 4 sigma of the average
  CHECK(f.mean_err_dph == Approx(300.0 / 306.0).margin(0.03));
  // The coil is still settling on the hold at 10 degC: the wall lags 2.5 degC at the end of
  // the 1 degC/min ramp and decays with 150 s, i.e. 0.34 degC at 1500 s and 0.05 at 1800 s.
  CHECK(f.t1_c > 10.0);
  CHECK(f.t1_c < 10.4);
  CHECK(f.rate_c_per_min < 0.0);
  CHECK(f.rate_c_per_min > -0.15);
  // Table 1 per step: the five steps, step 2 the worst.
  REQUIRE(c->steps.size() == 5);
  CHECK(c->steps[2].step == 2);
  CHECK(c->steps[2].stats.comp_std > 2.0 * c->steps[0].stats.comp_std);
  CHECK(c->verification.phases.size() == 3);
  CHECK(c->residual_dph.size() == bad.size());
  // The clean run: nothing fails.
  auto ok = wb::compare(m, clean);
  REQUIRE(ok);
  CHECK(ok->failures.empty());
  CHECK(ok->adequate());
  // A shorter minimum duration is still a minimum: 400 s is longer than the interval.
  wb::CompareOptions o;
  o.noise.max_fail_s = 400.0;
  auto none = wb::compare(m, bad, o);
  REQUIRE(none);
  CHECK(none->failures.empty());
  o.noise.smooth_s = 60;
  auto badopt = wb::compare(m, bad, o);
  REQUIRE_FALSE(badopt);
  CHECK(badopt.error().message.find("odd") != std::string::npos);
}

TEST_CASE("workbench: add_term refuses bad terms with a message that says why") {
  const RunData r = make_run(3000, 3);
  const Model m = fit_d(r);
  auto unknown = wb::add_term(m, r, "T9");
  REQUIRE_FALSE(unknown);
  CHECK(unknown.error().code == FitError::Code::bad_term);
  CHECK(unknown.error().message.find("position") != std::string::npos);
  auto twice = wb::add_term(m, r, "d(T1)");
  REQUIRE_FALSE(twice);
  CHECK(twice.error().message.find("already has") != std::string::npos);
  auto with_coef = wb::add_term(m, r, "0.05*T1");
  REQUIRE_FALSE(with_coef);
  CHECK(with_coef.error().message.find("without a coefficient") != std::string::npos);
  auto no_ta = wb::add_term(m, r, "Ta");  // make_run records no chamber temperature
  REQUIRE_FALSE(no_ta);
  CHECK(no_ta.error().code == FitError::Code::missing_signal);
  CHECK(no_ta.error().message.find("chamber_c") != std::string::npos);
}

TEST_CASE("workbench: add_term records the parent and lineage lists root first") {
  // A hidden 0.05 deg/h per degC of T1: the T1 excursion of -10..+10 degC gives +-0.5 deg/h.
  const RunData r = make_run(5000, 4, [](std::size_t, double t1) { return 0.05 * (t1 - 20.0); });
  const Model m = fit_d(r);
  auto a = wb::add_term(m, r, "T1");
  REQUIRE(a);
  CHECK(a->added == "T1");
  REQUIRE(a->model.terms.size() == 2);
  CHECK(a->model.terms[1].coef == Approx(0.05).margin(0.005));  // se about 0.001 at 5000 samples
  REQUIRE(a->model.parent);
  CHECK(a->model.parent->terms.size() == 1);
  // The parent survives the JSON round trip.
  auto back = model_from_json(to_json(a->model));
  REQUIRE(back);
  REQUIRE(back->parent);
  CHECK(back->note == a->model.note);
  const std::vector<RunData> runs{r};
  const auto l = wb::lineage(*back, runs);
  REQUIRE(l.steps.size() == 2);
  CHECK(l.steps[0].terms == m.terms_string());
  // Before: the T1 error's std over the run (about 0.35 deg/h) on top of the noise; after: the noise.
  CHECK(l.steps[0].comp_std_dph[0] > 0.25);
  CHECK(l.steps[1].comp_std_dph[0] == Approx(0.146).margin(0.01));
  const auto j = wb::to_json(l);
  CHECK(j["lineage"].size() == 2);
}

TEST_CASE("workbench: diagnose on a run too short for the lags says so") {
  const RunData longer = make_run(3000, 5);
  const Model m = fit_d(longer);
  const RunData short_run = make_run(400, 6);
  auto d = wb::diagnose(m, short_run, {});
  REQUIRE_FALSE(d);
  CHECK(d.error().code == FitError::Code::too_short);
  CHECK(d.error().message.find("too short") != std::string::npos);
  // A short held-out run is scored, not fatal: the model predicts on any length.
  const std::vector<RunData> held{short_run};
  auto d2 = wb::diagnose(m, longer, held);
  REQUIRE(d2);
  const auto j = wb::to_json(*d2);
  CHECK(j["adequate"].is_boolean());
  REQUIRE(!j["candidates"].empty());
  for (const char* k : {"term", "effect", "lag_s", "rms_before", "rms_after", "delta_bic", "p_value", "held_out"})
    CHECK(j["candidates"][0].contains(k));
}

TEST_CASE("workbench: decimation keeps the extremes, in time order") {
  std::vector<double> y(100000, 0.0);
  y[51234] = 5.0;   // a one-sample spike
  y[70000] = -3.0;
  const auto idx = wb::decimate_indices(y, 2000);
  CHECK(idx.size() <= 2000);
  CHECK(std::is_sorted(idx.begin(), idx.end()));
  CHECK(std::find(idx.begin(), idx.end(), 51234u) != idx.end());
  CHECK(std::find(idx.begin(), idx.end(), 70000u) != idx.end());
  const std::vector<double> few(10, 1.0);
  CHECK(wb::decimate_indices(few, 2000).size() == 10);
  // A moving average leaves a straight line unchanged away from the ends.
  std::vector<double> line(200);
  for (std::size_t i = 0; i < line.size(); ++i) line[i] = 0.5 * static_cast<double>(i);
  const auto ma = wb::moving_average(line, 61);
  CHECK(ma[100] == Approx(50.0));
}

TEST_CASE("workbench: the qualification summary's hysteresis and ramp excursion") {
  const RunData r = make_run(5000, 7);
  const Model m = fit_d(r);
  const std::vector<RunData> runs{r};
  const bool held[] = {false};
  const auto q = wb::qualify(m, runs, held);
  REQUIRE(q.runs.size() == 1);
  const auto& x = q.runs[0];
  // The gyro is -3 deg/h per degC/min of d(T1): on the ramps at +1 and -1 degC/min it sits
  // at -3 and +3 deg/h from mu0, so at equal T1 heating minus cooling is -6 deg/h where both
  // ramps are steady, less near the ramps' ends (10..20 degC is visited by both; the ends
  // carry the coil's 190 s transients), and the peak excursion is 3 deg/h.
  CHECK(x.hysteresis_dph < -4.0);
  CHECK(x.hysteresis_dph > -6.2);
  // The model is the truth: compensated, heating and cooling agree within the noise of bin
  // means (0.146 deg/h over hundreds of samples: a few 0.01 deg/h).
  CHECK(std::abs(x.hysteresis_comp_dph) < 0.05);
  CHECK(x.peak_ramp_excursion_dph == Approx(3.0).margin(0.15));
  CHECK(x.pass);
  CHECK(q.pass);
  REQUIRE(q.sensitivities.size() == 1);
  CHECK(q.sensitivities[0].coef == Approx(-3.0).margin(0.05));
  CHECK(q.sensitivities[0].unit == "deg/h per degC/min");
  const auto j = wb::to_json(q);
  CHECK(j["runs"][0].contains("hysteresis_comp_dph"));
}

TEST_CASE("workbench: flagged and missing gyro samples do not spoil diagnose and compare") {
  // A hidden 0.05 deg/h per degC of T1, as in the lineage test. The fit run has 40 flagged
  // samples and 40 missing readings (NaN); the held-out run 40 missing readings. Both are
  // skipped by every sum (the core's fit alone fails on a NaN, even at weight 0: diagnose
  // hands it a copy with those samples flagged missing).
  auto hidden = [](std::size_t, double t1) { return 0.05 * (t1 - 20.0); };
  RunData r = make_run(5000, 8, hidden);
  r.flags.assign(r.size(), 0);
  for (std::size_t t = 750; t < 4750; t += 100) r.flags[t] = flag::frames_lost;
  const Model m = fit_d(r);
  for (std::size_t t = 720; t < 4720; t += 100) r.gyro_dph[t] = std::numeric_limits<double>::quiet_NaN();
  RunData h = make_run(5000, 9, hidden);
  for (std::size_t t = 700; t < 4700; t += 100) h.gyro_dph[t] = std::numeric_limits<double>::quiet_NaN();
  const std::vector<RunData> held{h};
  auto d = wb::diagnose(m, r, held);
  REQUIRE(d);
  INFO(d->summary);
  CHECK(std::isfinite(d->rms_fit_dph));
  REQUIRE(!d->candidates.empty());
  const auto& top = d->candidates.front();
  CHECK(top.expr == "T1");
  CHECK(top.detected);
  CHECK(std::isfinite(top.delta_bic));
  REQUIRE(top.held_out.size() == 1);
  CHECK(top.held_out[0].scored);
  CHECK(std::isfinite(top.held_out[0].rms_after_dph));
  auto c = wb::compare(m, h);
  REQUIRE(c);
  CHECK(!c->failures.empty());
  for (const auto& f : c->failures) CHECK(std::isfinite(f.mean_err_dph));
  auto a = wb::add_term(m, r, "T1");
  REQUIRE(a);
  CHECK(a->model.terms.back().coef == Approx(0.05).margin(0.005));
}

TEST_CASE("workbench: diagnose reports its progress and neither the callback nor the threads change the answer") {
  auto hidden = [](std::size_t, double t1) { return 0.05 * (t1 - 20.0); };
  const RunData r = make_run(5000, 8, hidden);
  const Model m = fit_d(r);
  const std::vector<RunData> held{make_run(5000, 9, hidden)};
  auto plain = wb::diagnose(m, r, held);
  REQUIRE(plain);
  wb::DiagnoseOptions o;
  o.threads = 2;
  std::vector<wb::DiagnoseProgress> seen;
  o.progress = [&](const wb::DiagnoseProgress& p) { seen.push_back(p); };
  auto told = wb::diagnose(m, r, held, o);
  REQUIRE(told);
  // Bit for bit the same answer (the JSON prints every number to its last digit).
  CHECK(wb::to_json(*told).dump() == wb::to_json(*plain).dump());
  REQUIRE(!seen.empty());
  CHECK(seen.front().stage == "base fit");
  CHECK(seen.back().stage == "adequacy checks");
  CHECK(seen.back().step == static_cast<int>(told->steps.size()));
  bool screened = false, refitted_all = false;
  for (std::size_t i = 0; i < seen.size(); ++i) {
    const auto& p = seen[i];
    screened = screened || (p.stage == "screening" && p.total > 0);
    if (p.stage != "refitting") continue;
    CHECK(p.done <= p.total);
    refitted_all = refitted_all || (p.total > 0 && p.done == p.total);
    if (i > 0 && seen[i - 1].stage == "refitting" && seen[i - 1].step == p.step) CHECK(p.done >= seen[i - 1].done);
  }
  CHECK(screened);
  CHECK(refitted_all);
}
