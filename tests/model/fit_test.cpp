// Fits on synthetic runs whose truth is known, every fit error, and the model's JSON.
#include <catch2/catch.hpp>
#include <cmath>
#include <limits>
#include <random>

#include "fogbench/model/json.hpp"
#include "fogbench/model/model.hpp"

using namespace fogbench::model;

namespace {

// A run of n seconds: 600 s hold at 20 degC, then T1 follows a smooth triangle of +-8 degC
// (period 3000 s) and T2 leads T1 by a wall lag, so grad varies differently from d(T1) at the
// turns. The gyro is mu0 + beta * d(T1)(t - lag) + 0.02*T1 (optional) + white noise.
RunData synthetic(std::size_t n, double beta, int lag, double t1_coef, double noise_dph, unsigned seed) {
  RunData r;
  r.name = "synthetic";
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> e(0.0, noise_dph), tn(0.0, 0.002);
  for (std::size_t i = 0; i < n; ++i) {
    const double t = static_cast<double>(i);
    const double u = t < 600 ? 0.0 : t - 600;
    const double tri = 8.0 * std::sin(2 * M_PI * u / 3000.0) + 2.0 * std::sin(2 * M_PI * u / 1100.0);
    r.time_s.push_back(t);
    r.t1_c.push_back(20.0 + tri);
    r.t2_c.push_back(20.0 + 8.0 * std::sin(2 * M_PI * (u + 60) / 3000.0) + 2.0 * std::sin(2 * M_PI * (u + 40) / 1100.0) * (u > 0));
  }
  // The true drift uses the same derivative filter the model uses.
  std::vector<double> t1(n);
  for (std::size_t i = 0; i < n; ++i) t1[i] = r.t1_c[i] - 20.0;
  const auto d = derivative_per_min(t1, 1.0);
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t j = i >= static_cast<std::size_t>(lag) ? i - static_cast<std::size_t>(lag) : 0;
    r.gyro_dph.push_back(-8.0 + beta * d[j] + t1_coef * t1[i] + e(rng));
  }
  for (auto& v : r.t1_c) v += tn(rng);
  for (auto& v : r.t2_c) v += tn(rng);
  return r;
}

}  // namespace

TEST_CASE("joint fit recovers mu0, a coefficient and its lag on a run with known truth") {
  // 20000 s with white noise 0.15 deg/h. The coefficient of d(T1) is determined to
  // se ~ 0.15 / (std of d(T1) * sqrt(N)); d(T1) swings about +-1 degC/min here, so se is
  // about 0.15/(0.6*141) = 0.002: a 0.02 tolerance is 10 se. The lag is exact to +-1 s.
  const RunData r = synthetic(20000, -3.0, 38, 0.0, 0.15, 1);
  FitOptions o;
  o.method = Method::joint;
  auto m = fit(r, *parse_terms("d(T1)@auto"), o);
  REQUIRE(m);
  CHECK(m->mu0_dph == Approx(-8.0).margin(0.01));
  CHECK(m->terms[0].coef == Approx(-3.0).margin(0.02));
  CHECK(std::abs(m->terms[0].term.lag.seconds - 38) <= 1);
  CHECK(m->sigma_a_dph == Approx(0.15).epsilon(0.05));
  // White noise: the estimated AR coefficients are within 4/sqrt(N) = 0.03 of zero.
  CHECK(std::abs(m->ar[0]) < 0.03);
  CHECK(std::abs(m->ar[1]) < 0.03);
  // The reported standard error is of the size derived above.
  CHECK(m->terms[0].se_dph_per_unit > 0.0005);
  CHECK(m->terms[0].se_dph_per_unit < 0.01);
  CHECK(m->fit.converged);
}

TEST_CASE("joint fit separates two terms with their own lags") {
  const RunData r = synthetic(20000, -3.0, 38, 0.05, 0.15, 2);
  FitOptions o;
  o.method = Method::joint;
  auto m = fit(r, *parse_terms("d(T1)@auto + T1@auto"), o);
  REQUIRE(m);
  CHECK(m->terms[0].coef == Approx(-3.0).margin(0.03));
  CHECK(std::abs(m->terms[0].term.lag.seconds - 38) <= 2);
  CHECK(m->terms[1].coef == Approx(0.05).margin(0.005));
  CHECK(m->terms[1].term.lag.seconds <= 30);  // the truth is 0; T1 is smooth so a few s is as good
}

TEST_CASE("the same term at two lags, two thermal paths, fits both (TERMS.md's 'a model term again at a second lag')") {
  // A second, slower path: the drift has d(T1) at 38 s and again at 300 s.
  RunData r = synthetic(20000, -3.0, 38, 0.0, 0.15, 12);
  std::vector<double> t1(r.size());
  for (std::size_t i = 0; i < r.size(); ++i) t1[i] = r.t1_c[i] - 20.0;
  const auto d = derivative_per_min(t1, 1.0);
  for (std::size_t i = 300; i < r.size(); ++i) r.gyro_dph[i] += -1.5 * d[i - 300];
  FitOptions o;
  o.method = Method::joint;
  SECTION("at fixed lags") {
    auto m = fit(r, *parse_terms("d(T1)@38 + d(T1)@300"), o);
    REQUIRE(m);
    CHECK(m->terms[0].coef == Approx(-3.0).margin(0.05));
    CHECK(m->terms[1].coef == Approx(-1.5).margin(0.05));
  }
  SECTION("both lags estimated") {
    auto m = fit(r, *parse_terms("d(T1)@auto + d(T1)@auto"), o);
    INFO((m ? std::string() : m.error().message));
    REQUIRE(m);
    const int a = m->terms[0].term.lag.seconds, b = m->terms[1].term.lag.seconds;
    const bool first_fast = a < b;
    INFO("lags " << a << " " << b << " coefs " << m->terms[0].coef << " " << m->terms[1].coef);
    CHECK(std::abs((first_fast ? a : b) - 38) <= 3);
    CHECK(std::abs((first_fast ? b : a) - 300) <= 3);
    CHECK(m->terms[first_fast ? 0 : 1].coef == Approx(-3.0).margin(0.1));
    CHECK(m->terms[first_fast ? 1 : 0].coef == Approx(-1.5).margin(0.1));
  }
  SECTION("at the same fixed lag it is one term twice") {
    auto m = fit(r, *parse_terms("d(T1)@38 + d(T1)@38"), o);
    REQUIRE_FALSE(m);
    CHECK_THAT(m.error().message, Catch::Contains("appears twice at the same lag"));
  }
}

TEST_CASE("paper fit takes mu0 and the AR noise from the opening hold and one shared lag") {
  const RunData r = synthetic(12000, -3.0, 38, 0.0, 0.15, 3);
  auto m = fit(r, *parse_terms("d(T1)@auto"), FitOptions{});
  REQUIRE(m);
  CHECK(m->method == Method::paper);
  CHECK(m->fit.n_hold == 600);
  // mu0 is the hold's mean: its se is 0.15/sqrt(600) = 0.006; 0.03 is 5 se.
  CHECK(m->mu0_dph == Approx(-8.0).margin(0.03));
  CHECK(m->terms[0].coef == Approx(-3.0).margin(0.05));
  CHECK(std::abs(m->terms[0].term.lag.seconds - 38) <= 2);
  CHECK(m->sigma_a_dph == Approx(0.15).epsilon(0.1));
}

TEST_CASE("prediction and verification: compensation removes the modelled drift") {
  const RunData r = synthetic(12000, -3.0, 38, 0.0, 0.15, 4);
  auto m = fit(r, *parse_terms("paper"), FitOptions{});
  REQUIRE(m);
  auto v = verify(*m, r);
  REQUIRE(v);
  // Raw std is dominated by the drift (about 3 * 0.6 = 1.8 deg/h); what is left is the noise.
  CHECK(v->run.meas_std > 1.0);
  CHECK(v->run.comp_std == Approx(0.15).epsilon(0.1));
  CHECK(v->pass);
  CHECK(v->run.ratio == Approx(v->run.comp_std / v->run.meas_std));
  // Phases come from T1's rate here (no setpoint): all three are present.
  CHECK(v->phases.size() == 3);
}

TEST_CASE("fit errors name what is wrong") {
  const RunData r = synthetic(6000, -3.0, 38, 0.0, 0.15, 5);
  FitOptions joint;
  joint.method = Method::joint;
  SECTION("collinear terms are named") {
    auto m = fit(r, *parse_terms("T1 + T2 + grad"), joint);
    REQUIRE_FALSE(m);
    CHECK(m.error().code == FitError::Code::collinear);
    CHECK_THAT(m.error().message, Catch::Contains("'T1'") && Catch::Contains("'T2'") && Catch::Contains("'grad'"));
  }
  SECTION("a term that does not vary") {
    RunData flat = r;
    for (auto& v : flat.t2_c) v = 25.0;
    auto m = fit(flat, *parse_terms("d(T2)"), joint);
    REQUIRE_FALSE(m);
    CHECK_THAT(m.error().message, Catch::Contains("'d(T2)' is constant"));
  }
  SECTION("the same term twice") {
    auto m = fit(r, *parse_terms("T1 + T1"), joint);
    REQUIRE_FALSE(m);
    CHECK_THAT(m.error().message, Catch::Contains("appears twice"));
  }
  SECTION("a run too short for the lags asked") {
    RunData s = synthetic(500, -3.0, 38, 0.0, 0.15, 6);
    auto m = fit(s, *parse_terms("paper"), FitOptions{});
    REQUIRE_FALSE(m);
    CHECK(m.error().code == FitError::Code::too_short);
    CHECK_THAT(m.error().message, Catch::Contains("500 samples") && Catch::Contains("600 s"));
  }
  SECTION("uneven time says where") {
    RunData u = r;
    for (std::size_t i = 1000; i < u.size(); ++i) u.time_s[i] += 1.0;
    auto m = fit(u, *parse_terms("paper"), FitOptions{});
    REQUIRE_FALSE(m);
    CHECK(m.error().code == FitError::Code::uneven_time);
    CHECK_THAT(m.error().message, Catch::Contains("samples 1000 and 1001") && Catch::Contains("2.0"));
  }
  SECTION("a term needing a signal the run lacks") {
    auto m = fit(r, *parse_terms("Ta"), joint);
    REQUIRE_FALSE(m);
    CHECK(m.error().code == FitError::Code::missing_signal);
  }
  SECTION("a fixed lag beyond the maximum") {
    auto m = fit(r, *parse_terms("T1@900"), joint);
    REQUIRE_FALSE(m);
    CHECK_THAT(m.error().message, Catch::Contains("900 s"));
  }
  SECTION("invalid options name the constraint") {
    FitOptions bad;
    bad.smooth_s = 60;
    auto m = fit(r, *parse_terms("paper"), bad);
    REQUIRE_FALSE(m);
    CHECK(m.error().code == FitError::Code::bad_options);
    CHECK_THAT(m.error().message, Catch::Contains("smooth_s"));
  }
}

TEST_CASE("flagged samples are skipped and counted") {
  RunData r = synthetic(12000, -3.0, 38, 0.0, 0.15, 7);
  r.flags.assign(r.size(), 0);
  for (std::size_t i = 5000; i < 5100; ++i) {
    r.flags[i] = flag::frames_lost;
    r.gyro_dph[i] = 1000.0;  // garbage that must not reach the fit
  }
  FitOptions o;
  o.method = Method::joint;
  auto m = fit(r, *parse_terms("d(T1)@auto"), o);
  REQUIRE(m);
  CHECK(m->fit.n_flagged == 100);
  CHECK(m->terms[0].coef == Approx(-3.0).margin(0.03));
}

TEST_CASE("a model saves to JSON and loads back exactly") {
  const RunData r = synthetic(8000, -3.0, 38, 0.02, 0.15, 8);
  FitOptions o;
  o.method = Method::joint;
  auto m = fit(r, *parse_terms("d(T1)@auto + T1 + lp(T2,120)@15"), o);
  REQUIRE(m);
  m->created_at = "2026-11-21T00:00:00Z";
  auto parent = fit(r, *parse_terms("paper"), FitOptions{});
  REQUIRE(parent);
  m->parent = std::make_shared<const Model>(*parent);
  const auto j = to_json(*m);
  auto back = model_from_text(j.dump());
  REQUIRE(back);
  CHECK(to_json(*back) == j);  // every field, doubles bit for bit (nlohmann prints round-trip digits)
  CHECK(back->terms[0].coef == m->terms[0].coef);
  CHECK(back->parent->terms_string() == parent->terms_string());
  // And its predictions are the same to the last bit.
  CHECK(*predict(*back, r) == *predict(*m, r));
}

TEST_CASE("model JSON errors name the field") {
  const auto j = to_json(*fit(synthetic(8000, -3.0, 38, 0.0, 0.15, 9), *parse_terms("paper"), FitOptions{}));
  auto broken = j;
  broken["terms"][1]["lag_s"] = "soon";
  auto r = model_from_json(broken);
  REQUIRE_FALSE(r);
  CHECK(r.error() == "terms[1].lag_s: expected an integer");
  broken = j;
  broken["terms"][0]["term"] = "d(T9)";
  r = model_from_json(broken);
  REQUIRE_FALSE(r);
  CHECK_THAT(r.error(), Catch::StartsWith("terms[0].term: unknown name 'T9'"));
  broken = j;
  broken.erase("mu0");
  CHECK(model_from_json(broken).error() == "mu0: missing");
  CHECK_FALSE(model_from_text("{not json"));
}

TEST_CASE("a reading not taken (NaN) is skipped by the fits, not poisoning them") {
  RunData r = synthetic(8000, -3.0, 38, 0.0, 0.15, 10);
  r.flags.assign(r.size(), 0);
  for (std::size_t i = 3000; i < 3010; ++i) {
    r.gyro_dph[i] = std::numeric_limits<double>::quiet_NaN();
    r.flags[i] = flag::missing;
  }
  for (auto method : {Method::paper, Method::joint}) {
    FitOptions o;
    o.method = method;
    auto m = fit(r, *parse_terms("d(T1)@auto"), o);
    REQUIRE(m);
    CHECK(std::isfinite(m->terms[0].coef));
    CHECK(m->fit.n_flagged == 10);
  }
}

TEST_CASE("verify keeps a sustained failure of the model in Table 1") {
  // A 300 s error of +1 deg/h that the model does not know: only spikes are outliers, so the
  // 300 samples stay and raise comp_std well above the noise (0.15 deg/h): the variance adds
  // 1^2 * 300/8000 = 0.0375, comp_std becomes sqrt(0.0225 + 0.0375 - (300/8000)^2) = 0.24.
  RunData r = synthetic(8000, -3.0, 38, 0.0, 0.15, 11);
  auto m = fit(r, *parse_terms("paper"), FitOptions{});
  REQUIRE(m);
  for (std::size_t i = 5000; i < 5300; ++i) r.gyro_dph[i] += 1.0;
  auto v = verify(*m, r);
  REQUIRE(v);
  CHECK(v->n_outliers < 50);
  CHECK(v->run.comp_std > 0.22);
}

TEST_CASE("a fit's summary says how it ended: converged, not converged, or failed and where") {
  // White noise 0.15 deg/h: the AR estimates start from 0 and the first iteration moves them
  // by about 1/sqrt(N) = 0.007 or more, far above the 1e-5 tolerance, so one iteration cannot
  // converge; the default 30 do (the first test above).
  const RunData r = synthetic(8000, -3.0, 38, 0.0, 0.15, 7);
  FitOptions o;
  o.method = Method::joint;
  auto done = fit(r, *parse_terms("d(T1)@auto"), o);
  REQUIRE(done);
  CHECK(done->fit.summary.termination == FitTermination::converged);
  CHECK(done->fit.summary.converged());
  CHECK(done->fit.summary.iterations == done->fit.iterations);
  CHECK(done->fit.summary.iterations > 1);
  CHECK(done->fit.summary.last_change < o.tolerance);

  o.max_iterations = 1;
  auto cut = fit(r, *parse_terms("d(T1)@auto"), o);
  REQUIRE(cut);  // still a model: the last iteration's estimates
  CHECK_FALSE(cut->fit.converged);
  CHECK(cut->fit.summary.termination == FitTermination::no_convergence);
  CHECK_FALSE(cut->fit.summary.converged());
  CHECK(cut->fit.summary.iterations == 1);
  CHECK(cut->fit.summary.last_change >= o.tolerance);
  CHECK(cut->fit.summary.why.find("max_iterations (1)") != std::string::npos);
  CHECK(cut->fit.summary.brief().find("NOT converged after 1 iteration") != std::string::npos);
  // The file keeps converged and iterations; the summary comes back from them.
  auto back = model_from_json(to_json(*cut));
  REQUIRE(back);
  CHECK(back->fit.summary.termination == FitTermination::no_convergence);
  CHECK(back->fit.summary.iterations == 1);
  CHECK(to_json(cut->fit.summary)["termination"] == "no_convergence");

  // The paper method does not iterate: converged, 0 iterations.
  auto paper = fit(r, *parse_terms("paper"));
  REQUIRE(paper);
  CHECK(paper->fit.summary.method == Method::paper);
  CHECK(paper->fit.summary.converged());
  CHECK(paper->fit.summary.iterations == 0);

  // A failure keeps its summary: where the fit stopped and why (the error's message).
  RunData short_run = r;
  for (auto* col : {&short_run.time_s, &short_run.gyro_dph, &short_run.t1_c, &short_run.t2_c}) col->resize(500);
  auto bad = fit(short_run, *parse_terms("d(T1)@auto"), o);
  REQUIRE_FALSE(bad);
  CHECK(bad.error().code == FitError::Code::too_short);
  CHECK(bad.error().summary.termination == FitTermination::failed);
  CHECK(bad.error().summary.method == Method::joint);
  CHECK(bad.error().summary.stage == "checks");
  CHECK(bad.error().summary.iterations == 0);
  CHECK(bad.error().summary.why == bad.error().message);
}
