// The firmware form of a model: each kind of operation against predict() on a synthetic run
// (exact once the windows hold real samples), the delays causality adds, and the refusals.
#include <catch2/catch.hpp>
#include <cmath>

#include "fogbench/model/firmware.hpp"

using namespace fogbench::model;

namespace {

// A run of 3,000 s: T1 holds, ramps at 1 degC/min, holds, ramps down at 0.5; T2 follows T1
// through a 200 s lag; Ta leads; the gyro powered on 100 s before the start.
RunData synthetic_run() {
  RunData r;
  r.name = "synthetic";
  double t2 = 20.0;
  for (int i = 0; i < 3000; ++i) {
    const double t = i;
    const double t1 = t < 600 ? 20.0 : t < 1200 ? 20.0 + (t - 600) / 60.0 : t < 2000 ? 30.0 : 30.0 - (t - 2000) / 120.0;
    t2 += (t1 - t2) / 200.0;
    r.time_s.push_back(t);
    r.t1_c.push_back(t1 + 0.01 * std::sin(0.37 * t));
    r.t2_c.push_back(t2);
    r.chamber_c.push_back(t1 + 0.5);
    r.since_power_on_s.push_back(100.0 + t);
    r.gyro_dph.push_back(0.0);
  }
  return r;
}

Model model_of(std::initializer_list<const char*> terms) {
  Model m;
  m.mu0_dph = 1.25;
  double coef = 0.5;
  for (const char* text : terms) {
    auto t = parse_term(text);
    REQUIRE(t);
    FittedTerm f;
    f.term = *t;
    f.coef = coef;
    coef *= -1.7;
    m.terms.push_back(f);
  }
  return m;
}

// Largest |firmware - predict| from sample `from` on, deg/h.
double worst_from(const Model& m, const RunData& r, std::size_t from) {
  auto p = firmware::compile(m);
  REQUIRE(p);
  auto mu = predict(m, r);
  REQUIRE(mu);
  firmware::Compensator c(*p);
  double worst = 0.0;
  for (std::size_t i = 0; i < r.size(); ++i) {
    const double v = c.step({r.t1_c[i], r.t2_c[i], r.chamber_c[i], r.since_power_on_s[i]});
    if (i >= from) worst = std::max(worst, std::abs(v - (*mu)[i]));
  }
  return worst;
}

}  // namespace

TEST_CASE("firmware: pointwise terms match predict from the first sample", "[firmware]") {
  const auto r = synthetic_run();
  // No slope: nothing is late and nothing waits for a window, so every sample matches.
  CHECK(worst_from(model_of({"T1", "grad@25", "Ta^2", "up(T2-T1)", "down(T1*T2)@7", "warm(600)", "lp(T1,300)@12"}), r, 0) < 1e-9);
}

TEST_CASE("firmware: slopes, second slopes and products of slopes match predict once windows are full",
          "[firmware]") {
  const auto r = synthetic_run();
  // d(T1)@30: a causal slope, no delay. dd(T1)@60: two slopes, 60 samples late, nothing more.
  // d(T1)*T2@45: T2 waits 30, then 15. (d(T1))^2@31. The fit's centred windows are whole from
  // sample lag + 30 (+30 more for dd); the causal ones from 60 (120 for dd) + the same lag.
  CHECK(worst_from(model_of({"d(T1)@30"}), r, 60) < 1e-9);
  CHECK(worst_from(model_of({"dd(T1)@60"}), r, 180) < 1e-9);
  CHECK(worst_from(model_of({"d(T1)*T2@45", "d(T2)^2@31", "up(d(T1))@40"}), r, 120) < 1e-9);
}

TEST_CASE("firmware: a delay around a slope absorbs its look-ahead (a second path, (d(T1)@300))", "[firmware]") {
  const auto r = synthetic_run();
  // (d(T1)@300) at lag 0 is d(T1)@300, the spelling diagnose gives a second path: causal, the
  // slope's 30 samples inside the 300 (it was refused as 30 s ahead). (d(T1)@20)@10: 20 of the
  // 30 inside the delay, the lag the other 10. Exact once the windows hold real samples.
  for (const char* text : {"(d(T1)@300)", "(d(T1)@20)@10", "(dd(T1)@100)", "(T1@40)*d(T2)@30"}) {
    INFO(text);
    auto p = firmware::compile(model_of({text}));
    INFO((p ? std::string() : p.error()));
    REQUIRE(p);
    CHECK(p->terms[0].late_s == 0);
  }
  CHECK(worst_from(model_of({"(d(T1)@300)"}), r, 360) < 1e-9);
  CHECK(worst_from(model_of({"(d(T1)@20)@10", "(dd(T1)@100)"}), r, 200) < 1e-9);
  CHECK(worst_from(model_of({"(T1@40)*d(T2)@30"}), r, 100) < 1e-9);
  // Short of the slope's half-window the rest is still ahead: (d(T1)@10) reads 20 s ahead.
  auto early = firmware::compile(model_of({"(d(T1)@10)"}));
  REQUIRE_FALSE(early);
  CHECK(early.error().find("20 s ahead") != std::string::npos);
}

TEST_CASE("firmware: the history each operation needs is counted", "[firmware]") {
  // d(T1)@30: one 61-sample window. dd(T1)@70: two windows and a 10-sample delay.
  auto p = firmware::compile(model_of({"d(T1)@30", "dd(T1)@70"}));
  REQUIRE(p);
  CHECK(p->ring_size == 61 + 61 + 61 + 10);
  CHECK(p->terms.size() == 2);
  CHECK(p->terms[1].name == "dd(T1)@70");
  CHECK(p->terms[0].unit == "deg/h per degC/min");
}

TEST_CASE("firmware: a term that reads the future is refused naming it, or computed late on request",
          "[firmware]") {
  const auto m = model_of({"grad@5", "dd(T1)@45"});
  auto p = firmware::compile(m);
  REQUIRE_FALSE(p);
  CHECK(p.error().find("term dd(T1)@45") != std::string::npos);
  CHECK(p.error().find("15 s ahead") != std::string::npos);
  CHECK(p.error().find("at least 60 s") != std::string::npos);
  // Late, the whole model is 15 s late, grad@5 too: terms shifted against each other would no
  // longer cancel where the model's do (d(T1) and grad on a distributed coil, r = 1.00).
  auto late = firmware::compile(m, 1.0, true);
  REQUIRE(late);
  CHECK(late->terms[0].late_s == 15);
  CHECK(late->terms[1].late_s == 15);
  const auto r = synthetic_run();
  auto mu = predict(m, r);
  REQUIRE(mu);
  firmware::Compensator c(*late);
  double worst = 0.0;
  for (std::size_t i = 0; i < r.size(); ++i) {
    const double v = c.step({r.t1_c[i], r.t2_c[i], r.chamber_c[i], r.since_power_on_s[i]});
    if (i >= 200) worst = std::max(worst, std::abs(v - (*mu)[i - 15]));  // mu(t - 15 s), exactly
  }
  CHECK(worst < 1e-9);
}

TEST_CASE("firmware: the least lag a causal form needs, per term", "[firmware]") {
  auto lag = [](const char* text) { return firmware::causal_lag_s(*parse_term(text)->expr); };
  CHECK(lag("grad") == 0);
  CHECK(lag("lp(T1,300)") == 0);
  CHECK(lag("d(T1)") == 30);
  CHECK(lag("dd(T1)") == 60);
  CHECK(lag("T1*d(T1)") == 30);
  CHECK(lag("(d(T1)@300)") == 0);
  CHECK(lag("(d(T1)@20)") == 10);
}

TEST_CASE("firmware: windows and delays are in seconds whatever the sample interval", "[firmware]") {
  // At 0.1 s per sample: the slope spans 60 s (601 samples, 300 samples late), d(T1)@40 waits
  // 100 more samples (10 s); grad@40 is 400 samples; lp's alpha is 1 - exp(-0.1 / 300).
  auto p = firmware::compile(model_of({"d(T1)@40", "grad@40", "lp(T1,300)"}), 0.1);
  REQUIRE(p);
  std::vector<int> slopes, delays;
  double alpha = 0.0;
  for (const auto& o : p->ops) {
    if (o.kind == firmware::Op::Kind::slope) slopes.push_back(o.n);
    if (o.kind == firmware::Op::Kind::delay) delays.push_back(o.n);
    if (o.kind == firmware::Op::Kind::lp) alpha = o.p;
  }
  CHECK(slopes == std::vector<int>{601});
  CHECK(delays == std::vector<int>{100, 400});
  CHECK(alpha == Approx(1.0 - std::exp(-0.1 / 300.0)).epsilon(1e-12));
  // The same model at 1 s: 61 samples, 10 and 40.
  auto q = firmware::compile(model_of({"d(T1)@40", "grad@40"}), 1.0);
  REQUIRE(q);
  CHECK(q->ring_size == 61 + 10 + 40);
}

TEST_CASE("firmware: a float build's arithmetic stays within its tolerance of the double one", "[firmware]") {
  const auto m = model_of({"d(T1)@40", "grad@40", "lp(T1,600)", "T1*d(T1)@35"});
  auto p = firmware::compile(m);
  REQUIRE(p);
  const auto r = synthetic_run();
  firmware::Compensator d(*p), f(*p, firmware::Precision::single_precision);
  double worst = 0.0, largest = 0.0;
  for (std::size_t i = 0; i < r.size(); ++i) {
    const firmware::Input in{r.t1_c[i], r.t2_c[i], r.chamber_c[i], r.since_power_on_s[i]};
    const double vd = d.step(in), vf = f.step(in);
    worst = std::max(worst, std::abs(vd - vf));
    largest = std::max(largest, std::abs(vd));
    CHECK(static_cast<double>(static_cast<float>(vf)) == vf);  // every value a float
  }
  // mu reaches ~|0.5 * 10| + ... deg/h: float's 6e-8 relative of terms of tens of deg/h, summed
  // over a few operations: well under 1e-3 deg/h, and not exact (it is float arithmetic).
  INFO("largest |mu| " << largest << " deg/h, largest float-double difference " << worst << " deg/h");
  CHECK(worst < 1e-3);
  CHECK(worst > 0.0);
}

TEST_CASE("firmware: the C reference implementation's limits are checked", "[firmware]") {
  // Eight terms of d(x)@600: each a 61-sample window and a 570-sample delay: 5,048 samples fit;
  // fourteen need 8,834, over the 8,192 the header holds.
  std::vector<const char*> many(14, "d(T1)@600");
  Model m;
  for (const char* text : many) {
    FittedTerm f;
    f.term = *parse_term(text);
    m.terms.push_back(f);
  }
  auto p = firmware::compile(m);
  REQUIRE_FALSE(p);
  CHECK(p.error().find("8834 samples of history") != std::string::npos);
  CHECK(p.error().find("8192") != std::string::npos);
  CHECK_FALSE(firmware::compile(m, 0.0));
}
