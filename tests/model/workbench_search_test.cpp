// Issue 10's pure parts on hand-made runs: the signal ton and warm(tau) in the term language,
// their limits and errors; the AR noise's std; verify's marginal verdict; the search's limit.
#include <catch2/catch.hpp>
#include <cmath>
#include <random>

#include "fogbench/model/workbench.hpp"

using namespace fogbench::model;
namespace wb = fogbench::model::workbench;

namespace {

// 3000 s: hold at 20 degC for 600 s, ramp to 30 at 1 degC/min, hold. T2 follows the setpoint
// through 150 s, T1 follows T2 through 40 s. The gyro: -8 deg/h - 10 deg/h per degC/min of
// d(T1) (raw std about 4 deg/h), white noise of 0.146 deg/h (seeded), plus a step from 1500 s.
RunData make_run(std::uint64_t seed, double extra_step_dph = 0.0) {
  RunData r;
  r.name = "synthetic";
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, 0.146);
  double t2 = 20.0, t1 = 20.0;
  std::vector<double> t1s;
  for (std::size_t t = 0; t < 3000; ++t) {
    const double sp = t < 600 ? 20.0 : std::min(30.0, 20.0 + static_cast<double>(t - 600) / 60.0);
    t2 += (sp - t2) * (1.0 - std::exp(-1.0 / 150.0));
    t1 += (t2 - t1) * (1.0 - std::exp(-1.0 / 40.0));
    r.time_s.push_back(static_cast<double>(t));
    r.t1_c.push_back(t1);
    r.t2_c.push_back(t2);
    r.setpoint_c.push_back(sp);
  }
  const auto rate = derivative_per_min(r.t1_c, 1.0);
  for (std::size_t t = 0; t < 3000; ++t) r.gyro_dph.push_back(-8.0 - 10.0 * rate[t] + noise(rng) + (t >= 1500 ? extra_step_dph : 0.0));
  return r;
}

}  // namespace

TEST_CASE("terms: ton and warm(tau) parse, print, carry their units and evaluate from the recorded column") {
  auto t = parse_term("warm(900)");
  REQUIRE(t);
  CHECK(to_string(*t->expr) == "warm(900)");
  CHECK(coef_unit(*t->expr) == "deg/h");  // exp(-ton/tau) has no unit
  CHECK(uses_signal(*t->expr, Signal::ton));
  CHECK_FALSE(uses_signal(*t->expr, Signal::T1));
  auto u = parse_term("ton");
  REQUIRE(u);
  CHECK(coef_unit(*u->expr) == "deg/h per s");
  CHECK(to_string(*parse_term("0.2*warm(300)@10")) == "warm(300)@10");

  // warm(300) at ton = 0, 300, 600 s: 1, e^-1, e^-2.
  const std::vector<double> t1(3, 0.0), ton{0.0, 300.0, 600.0};
  Signals s{t1, t1, {}, 1.0, ton};
  auto v = evaluate(*t->expr, s);
  REQUIRE(v);
  auto w = evaluate(*parse_term("warm(300)")->expr, s);
  REQUIRE(w);
  CHECK((*w)[0] == Approx(1.0));
  CHECK((*w)[1] == Approx(std::exp(-1.0)));
  CHECK((*w)[2] == Approx(std::exp(-2.0)));

  // Without the column: an error that names the signal and the column, never a guess.
  Signals none{t1, t1, {}, 1.0};
  auto e = evaluate(*t->expr, none);
  REQUIRE_FALSE(e);
  CHECK(e.error().find("ton") != std::string::npos);
  CHECK(e.error().find("since_power_on_s") != std::string::npos);
}

TEST_CASE("terms: a time constant, power or lag out of range is an error naming the limit") {
  auto a = parse_term("warm(0.5)");
  REQUIRE_FALSE(a);
  CHECK(a.error().message.find("1 to 86400 s") != std::string::npos);
  auto b = parse_term("lp(T1, 100000)");
  REQUIRE_FALSE(b);
  CHECK(b.error().message.find("1 to 86400 s") != std::string::npos);
  auto c = parse_term("T1^5");
  REQUIRE_FALSE(c);
  CHECK(c.error().message.find("1 to 4") != std::string::npos);
  auto d = parse_term("T1@90000");
  REQUIRE_FALSE(d);
  CHECK(d.error().message.find("86400") != std::string::npos);
  auto e = parse_term("warm(T1)");
  REQUIRE_FALSE(e);
}

TEST_CASE("fit: a term using ton on a run without since_power_on_s names the term and the column") {
  RunData r = make_run(1);
  auto m = fit(r, *parse_terms("d(T1)@auto + warm(600)"), FitOptions{.method = Method::joint});
  REQUIRE_FALSE(m);
  CHECK(m.error().code == FitError::Code::missing_signal);
  CHECK(m.error().message.find("warm(600)") != std::string::npos);
  CHECK(m.error().message.find("since_power_on_s") != std::string::npos);
  // With the column it fits, and the warm-up's coefficient comes back (0.5 deg/h put in).
  for (std::size_t t = 0; t < r.size(); ++t) {
    r.since_power_on_s.push_back(120.0 + r.time_s[t]);
    r.gyro_dph[t] += 0.5 * std::exp(-r.since_power_on_s[t] / 600.0);
  }
  auto m2 = fit(r, *parse_terms("d(T1)@auto + warm(600)"), FitOptions{.method = Method::joint});
  REQUIRE(m2);
  // 0.5 within 4 standard errors (the se is ~0.03 deg/h here).
  CHECK(std::abs(m2->terms[1].coef - 0.5) < 4.0 * m2->terms[1].se_dph_per_unit);
}

TEST_CASE("stats: the std an AR process's noise implies") {
  const std::vector<double> none;
  CHECK(ar_process_std(none, 0.146) == Approx(0.146));
  // AR(1) with k = 0.5: sigma_a / sqrt(1 - k^2) = 0.146 / sqrt(0.75).
  const std::vector<double> k1{0.5};
  CHECK(ar_process_std(k1, 0.146) == Approx(0.146 / std::sqrt(0.75)).epsilon(1e-9));
  // AR(2): var = sigma_a^2 (1 - k2) / ((1 + k2) ((1 - k2)^2 - k1^2)); the paper's k1 -0.005,
  // k2 -0.04: 1.04 / (0.96 (1.0816 - 0.000025)) = 1.00163, so 0.146 * 1.000815.
  const std::vector<double> k2{-0.005, -0.04};
  const double var = (1.04) / (0.96 * (1.04 * 1.04 - 0.005 * 0.005));
  CHECK(ar_process_std(k2, 0.146) == Approx(0.146 * std::sqrt(var)).epsilon(1e-9));
  // Not stable: infinite.
  const std::vector<double> unstable{1.2};
  CHECK(std::isinf(ar_process_std(unstable, 0.146)));
}

TEST_CASE("verify: a run that passes the paper's ratio but keeps a visible error is marginal") {
  const RunData clean = make_run(3);
  // The drift is made from d(T1) at lag 0 (the centred slope): fitted from lag 0, not held at
  // the 30 s a firmware form needs, so that the model is the drift and only the step shows.
  auto m = fit(clean, *parse_terms("d(T1)@auto"), FitOptions{.method = Method::joint, .causal_lags = false});
  REQUIRE(m);
  auto v = verify(*m, clean);
  REQUIRE(v);
  CHECK(v->ratio_pass);
  CHECK(v->verdict == Verdict::pass);
  CHECK(v->pass);
  CHECK(v->noise_factor < 1.2);
  // +0.6 deg/h from 1500 s (the model fitted without it): the residual's 61 s average is 0.6
  // deg/h for 1500 s, beyond 3 sigma_a = 0.44; comp std sqrt(0.146^2 + 0.3^2) = 0.33 deg/h,
  // 2.3 x the noise, and still 8% of the raw std (about 4 deg/h): the paper's rule passes it.
  const RunData stepped = make_run(3, 0.6);
  auto w = verify(*m, stepped);
  REQUIRE(w);
  INFO("ratio " << w->run.ratio << " factor " << w->noise_factor << " longest " << w->longest_fail_s);
  CHECK(w->ratio_pass);
  CHECK(w->verdict == Verdict::marginal);
  CHECK_FALSE(w->pass);
  CHECK(w->longest_fail_s >= 60.0);
  CHECK_FALSE(w->reasons.empty());
  // The second test off: the paper's rule alone passes it.
  VerifyOptions off;
  off.noise_test = false;
  auto x = verify(*m, stepped, off);
  REQUIRE(x);
  CHECK(x->verdict == Verdict::pass);
  // Bad options name the option.
  VerifyOptions bad;
  bad.noise.max_noise_factor = 0.5;
  auto y = verify(*m, stepped, bad);
  REQUIRE_FALSE(y);
  CHECK(y.error().message.find("noise factor") != std::string::npos);
}

TEST_CASE("diagnose: a search beyond its candidate limit is refused, naming the limit") {
  const RunData r = make_run(5);
  auto m = fit(r, *parse_terms("paper"));
  REQUIRE(m);
  wb::DiagnoseOptions o;
  o.max_lag_s = 100;
  o.tau_points = 24;
  o.max_candidates = 150;
  auto d = wb::diagnose(*m, r, {}, o);
  REQUIRE_FALSE(d);
  CHECK(d.error().code == FitError::Code::bad_options);
  CHECK(d.error().message.find("over the limit of 150") != std::string::npos);
  o.max_terms = 7;
  auto e = wb::diagnose(*m, r, {}, o);
  REQUIRE_FALSE(e);
  CHECK(e.error().message.find("max_terms") != std::string::npos);
}
