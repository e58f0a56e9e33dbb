// The term language: parsing, errors with positions, canonical spelling, evaluation.
#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <cstdint>
#include <string>
#include <thread>
#include <vector>

#include "fogbench/model/terms.hpp"

using namespace fogbench::model;

TEST_CASE("paper expands to the paper's two terms with automatic lags") {
  auto l = parse_terms("paper");
  REQUIRE(l);
  CHECK(l->paper);
  REQUIRE(l->terms.size() == 2);
  CHECK(to_string(l->terms[0]) == "d(T1)@auto");
  CHECK(to_string(l->terms[1]) == "grad@auto");
}

TEST_CASE("every form of TERMS.md parses and prints canonically") {
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"d(T1)@auto + grad@auto", "d(T1)@auto + grad@auto"},
      {"T1", "T1"},
      {"T1^2", "T1^2"},
      {"T2 + d( T2 )", "T2 + d(T2)"},
      {"d(grad)", "d(grad)"},
      {"dd(T1)", "dd(T1)"},
      {"T1*d(T1)@40", "T1*d(T1)@40"},
      {"up(d(T1)) + down(d(T1))", "up(d(T1)) + down(d(T1))"},
      {"Ta + d(Ta)@12s", "Ta + d(Ta)@12"},
      {"lp(T1, 300)", "lp(T1,300)"},
      {"d(T1)@0", "d(T1)"},
  };
  for (const auto& [in, out] : cases) {
    INFO(in);
    auto l = parse_terms(in);
    REQUIRE(l);
    CHECK(to_string(*l) == out);
    // The canonical spelling parses back to itself.
    auto again = parse_terms(to_string(*l));
    REQUIRE(again);
    CHECK(to_string(*again) == out);
  }
}

TEST_CASE("coefficients in front of terms: effects for the simulator") {
  auto l = parse_terms("0.05*T1 - 2.5*d(T1)@38 + -0.387*grad@38");
  REQUIRE(l);
  REQUIRE(l->terms.size() == 3);
  CHECK(l->terms[0].coef == Approx(0.05));
  CHECK(l->terms[1].coef == Approx(-2.5));
  CHECK(l->terms[1].lag.seconds == 38);
  CHECK(l->terms[2].coef == Approx(-0.387));
  CHECK(to_string(*l->terms[1].expr) == "d(T1)");
}

TEST_CASE("parse errors give the position and what was expected") {
  struct Case {
    const char* text;
    std::size_t position;
    const char* needle;
  };
  const Case cases[] = {
      {"T3", 0, "unknown name 'T3'"},
      {"d(T1", 4, "expected ')'"},
      {"T1 +", 4, "expected a signal"},
      {"d(T1)@", 6, "expected a lag in seconds or 'auto'"},
      {"T1 T2", 3, "expected '+', '-', '*', '@' or the end"},
      {"lp(T1)", 5, "expected ',' and a time constant"},
      {"2*3", 3, "found only a number"},
      {"d(T1@auto)", 5, "'@auto' is allowed only at the end"},
      {"T1^9", 3, "exponent must be 1 to 4"},
      // The exponent's own message, not a lag's: '^' and '@' share the integer reader.
      {"T1^-1", 3, "exponent must be 1 to 4, got -1"},
      {"T1^ 99999999999999999999", 4, "99999999999999999999 is too large for an integer exponent"},
      {"T1@-1", 3, "a lag cannot be negative"},
      {"T1@99999999999", 3, "lag of 99999999999 s is longer than a day (86400 s)"},
      {"d(T1@90000)", 5, "lag of 90000 s is longer than a day"},
      {"", 0, "empty"},
  };
  for (const auto& c : cases) {
    INFO(c.text);
    auto l = parse_terms(c.text);
    REQUIRE_FALSE(l);
    CHECK(l.error().position == c.position);
    CHECK_THAT(l.error().message, Catch::Contains(c.needle));
    // pretty() shows the text and a caret under the position.
    CHECK_THAT(l.error().pretty(), Catch::Contains(std::string(c.position, ' ') + "^"));
  }
}

TEST_CASE("units of coefficients") {
  CHECK(coef_unit(*parse_term("d(T1)")->expr) == "deg/h per degC/min");
  CHECK(coef_unit(*parse_term("grad")->expr) == "deg/h per degC");
  CHECK(coef_unit(*parse_term("T1^2")->expr) == "deg/h per degC^2");
  CHECK(coef_unit(*parse_term("dd(T1)")->expr) == "deg/h per degC/min^2");
  CHECK(coef_unit(*parse_term("T1*d(T1)")->expr) == "deg/h per degC^2/min");
}

TEST_CASE("derivative of a ramp is its slope in degC/min, also at the ends") {
  // x = 0.5 degC per sample (1 s): 30 degC/min. A least-squares slope of a straight line is
  // exact for any window, so also where the window is cut at the ends.
  std::vector<double> x(500);
  for (std::size_t i = 0; i < x.size(); ++i) x[i] = 0.5 * static_cast<double>(i);
  const auto d = derivative_per_min(x, 1.0);
  for (double v : d) CHECK(v == Approx(30.0));
}

TEST_CASE("derivative on a long run keeps its digits: each window's slope as summed directly, at 900,000 samples") {
  // A temperature of about 25 degC swinging +-10 degC over 2 h with a little noise. Prefix sums
  // of i x_i over the whole run lost digits as n^2 x grew: a relative error of 3e-3 of the rate
  // at 864,000 samples. Each window summed directly in long double is the reference.
  const std::size_t n = 900'000;
  std::vector<double> x(n);
  std::uint64_t st = 12345;
  for (std::size_t i = 0; i < n; ++i) {
    st = st * 6364136223846793005ULL + 1442695040888963407ULL;
    const double u = static_cast<double>(st >> 11) / 9007199254740992.0 - 0.5;
    x[i] = 25.0 + 10.0 * std::sin(2.0 * 3.141592653589793 * static_cast<double>(i) / 7200.0) + 0.01 * u;
  }
  const auto d = derivative_per_min(x, 1.0);
  double worst = 0.0;
  for (std::size_t i : {std::size_t{0}, std::size_t{7}, std::size_t{29}, std::size_t{30}, std::size_t{1000}, std::size_t{262'199},
                        std::size_t{500'001}, std::size_t{863'999}, n - 31, n - 30, n - 1}) {
    const std::size_t lo = i >= 30 ? i - 30 : 0, hi = std::min(n - 1, i + 30);
    long double num = 0.0L, den = 0.0L;
    const long double c = 0.5L * (static_cast<long double>(lo) + static_cast<long double>(hi));
    for (std::size_t k = lo; k <= hi; ++k) {
      num += (static_cast<long double>(k) - c) * static_cast<long double>(x[k]);
      den += (static_cast<long double>(k) - c) * (static_cast<long double>(k) - c);
    }
    const double want = static_cast<double>(num / den * 60.0L);
    INFO("sample " << i << ": " << d[i] << " against " << want);
    // The swing's rate is up to 0.52 degC/min: 1e-9 of it.
    CHECK(std::abs(d[i] - want) < 5e-10);
    worst = std::max(worst, std::abs(d[i] - want));
  }
  INFO("worst " << worst);
  CHECK(worst < 5e-10);
}

TEST_CASE("derivative: a value that is not finite spoils only the windows that hold it") {
  std::vector<double> x(1000);
  for (std::size_t i = 0; i < x.size(); ++i) x[i] = 0.25 * static_cast<double>(i);  // 15 degC/min
  x[500] = std::nan("");
  const auto d = derivative_per_min(x, 1.0);
  for (std::size_t i = 0; i < x.size(); ++i) {
    INFO("sample " << i);
    if (i + 30 >= 500 && i <= 530) CHECK(std::isnan(d[i]));
    else CHECK(d[i] == Approx(15.0));
  }
}

TEST_CASE("evaluation of operators over signals") {
  const std::size_t n = 400;
  std::vector<double> t1(n), t2(n, 1.0);
  for (std::size_t i = 0; i < n; ++i) t1[i] = i < 200 ? 0.0 : (static_cast<double>(i) - 200.0) / 60.0;  // 1 degC/min from t=200
  Signals s{t1, t2, {}, 1.0};
  auto grad = evaluate(*parse_term("grad")->expr, s);
  REQUIRE(grad);
  CHECK((*grad)[300] == Approx(t1[300] - 1.0));
  // d(T1) well inside the ramp (window 270..330 all on the ramp) is 1 degC/min, 0 well before.
  auto d = evaluate(*parse_term("d(T1)")->expr, s);
  CHECK((*d)[300] == Approx(1.0));
  CHECK((*d)[100] == Approx(0.0).margin(1e-12));
  // up() keeps heating, down() keeps cooling.
  auto down = evaluate(*parse_term("down(d(T1))")->expr, s);
  CHECK((*down)[300] == Approx(0.0));
  // A fixed delay inside an expression: T1@60 at t=300 is T1 at t=240.
  auto del = evaluate(*parse_term("(T1@60)")->expr, s);
  CHECK((*del)[300] == Approx(t1[240]));
  // lp of a step: after one time constant, 1 - 1/e of the way (exact discretisation).
  std::vector<double> step(n, 0.0);
  for (std::size_t i = 100; i < n; ++i) step[i] = 1.0;
  Signals ss{step, t2, {}, 1.0};
  auto lp = evaluate(*parse_term("lp(T1, 50)")->expr, ss);
  CHECK((*lp)[149] == Approx(1.0 - std::exp(-50.0 / 50.0)));
  // Squares and products.
  auto sq = evaluate(*parse_term("T1^2")->expr, s);
  CHECK((*sq)[320] == Approx(t1[320] * t1[320]));
}

TEST_CASE("a term on Ta fails clearly when the run has no chamber temperature") {
  std::vector<double> t(100, 0.0);
  Signals s{t, t, {}, 1.0};
  auto v = evaluate(*parse_term("d(Ta)")->expr, s);
  REQUIRE_FALSE(v);
  CHECK_THAT(v.error(), Catch::Contains("chamber_c"));
}

TEST_CASE("one spelling per term: what fuzzing found") {
  // Each input must print to a spelling that parses back to the same spelling (and the same
  // coefficient), the property the term fuzzer checks.
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"(T1*5)", "T1"},            // the 5 is the coefficient
      {"(-T1)", "T1"},             // so is the sign
      {"(d(T1)@0)", "d(T1)"},      // a zero delay is no delay
      {"(T1@1)@1", "(T1@1)@1"},    // a delayed expression with its own lag
      {"(T1@30)*T2", "(T1@30)*T2"},
      {"d((T1@5))", "d((T1@5))"},
      {"d((-T2)*T2)", "d((-T2)*T2)"},  // not d(-(T2*T2))
      {"d(-T2*T2)", "d(-(T2*T2))"},
      {"d(T1 + -T2)", "d(T1+(-T2))"},
  };
  for (const auto& [in, out] : cases) {
    INFO(in);
    auto l = parse_terms(in);
    REQUIRE(l);
    CHECK(to_string(*l) == out);
    auto again = parse_terms(to_string(*l));
    REQUIRE(again);
    CHECK(to_string(*again) == out);
  }
  auto c = parse_terms("(T1*5)");
  CHECK(c->terms[0].coef == 5.0);
  CHECK(parse_terms("(-T1)")->terms[0].coef == -1.0);
  // A constant is not a term, and hostile nesting is refused before it can overflow the stack.
  auto k = parse_terms("(-2)");
  REQUIRE_FALSE(k);
  CHECK_THAT(k.error().message, Catch::Contains("only a number"));
  CHECK_THAT(parse_terms("d(2)").error().message, Catch::Contains("must contain a signal"));
  auto deep = parse_terms(std::string(10000, '(') + "T1" + std::string(10000, ')'));
  REQUIRE_FALSE(deep);
  CHECK_THAT(deep.error().message, Catch::Contains("nested deeper"));
  // Numbers folded at parse time must stay numbers: 1e300^4 printed as 'inf', which no
  // longer parsed; now it is refused where the exponent stands, as are factors whose product
  // overflows.
  auto big = parse_terms("d(T1--1e300^4*\t.0-0)");
  REQUIRE_FALSE(big);
  CHECK(big.error().position == 12);  // the exponent
  CHECK_THAT(big.error().message, Catch::Contains("out of the range of a double"));
  auto product = parse_terms("1e200*1e200*T1");
  REQUIRE_FALSE(product);
  CHECK_THAT(product.error().message, Catch::Contains("out of the range of a double"));
  CHECK(parse_terms("1e150*1e150*T1")->terms[0].coef == Approx(1e300));
  // A time constant is a finite number too (from_chars would read 'inf').
  auto inf_tau = parse_terms("lp(T1, inf)");
  REQUIRE_FALSE(inf_tau);
  CHECK_THAT(inf_tau.error().message, Catch::Contains("finite number"));
}

// RateMemo (diagnose's language search): evaluate with the memo must give evaluate's numbers bit
// for bit, for every form that contains a bare signal's rate, from several threads at once; an
// expression it cannot serve (a missing signal, another run's signals) behaves as without it.
TEST_CASE("evaluate with the rates memo gives evaluate's numbers exactly, shared by threads") {
  const std::size_t n = 3000;
  std::vector<double> t1(n), t2(n), ta(n);
  for (std::size_t i = 0; i < n; ++i) {
    const double u = static_cast<double>(i);
    t1[i] = 5.0 * std::sin(u / 300.0) + 1e-3 * std::cos(u * 1.7);
    t2[i] = 4.0 * std::sin(u / 330.0 - 0.2) + 1e-3 * std::sin(u * 2.3);
    ta[i] = 6.0 * std::sin(u / 250.0 + 0.1);
  }
  const Signals s{t1, t2, ta, 0.5};
  const std::vector<std::string> exprs = {"d(T1)",       "d(T2)",         "d(grad)",      "d(Ta)",          "dd(T1)",      "dd(T2)",
                                          "up(d(T1))",   "down(d(grad))", "T1*d(T2)",     "d(T1)*d(Ta)",    "d(lp(T1,300))", "lp(d(T2),300)",
                                          "d(T1)^2",     "T1",            "d(T1)*d(T1)",  "grad*d(grad)"};
  RateMemo memo(s);
  auto check_all = [&](int& mismatches) {
    for (const auto& e : exprs) {
      const auto t = parse_term(e);
      const auto a = evaluate(*t->expr, s);
      const auto b = evaluate(*t->expr, s, &memo);
      if (!a || !b || *a != *b) ++mismatches;  // operator== on doubles: exact
    }
  };
  int m0 = 0, m1 = 0, m2 = 0;
  std::thread th1([&] { check_all(m1); });
  std::thread th2([&] { check_all(m2); });
  th1.join();
  th2.join();
  check_all(m0);  // every rate kept now: served from the memo
  CHECK(m0 == 0);
  CHECK(m1 == 0);
  CHECK(m2 == 0);
  CHECK(memo.computed() == 4);  // T1, T2, grad, Ta: each once

  // The memo's rate is d(T1) itself, not T1 or another signal's.
  const auto d1 = evaluate(*parse_term("d(T1)")->expr, s, &memo);
  const auto d2 = evaluate(*parse_term("d(T2)")->expr, s, &memo);
  REQUIRE(d1);
  REQUIRE(d2);
  CHECK((*d1)[1500] == derivative_per_min(t1, 0.5)[1500]);
  CHECK((*d1)[1500] != (*d2)[1500]);

  // A signal the run lacks: evaluate's error, with or without the memo.
  const Signals no_ta{t1, t2, {}, 0.5};
  RateMemo memo2(no_ta);
  const auto ea = evaluate(*parse_term("T1*d(Ta)")->expr, no_ta);
  const auto eb = evaluate(*parse_term("T1*d(Ta)")->expr, no_ta, &memo2);
  REQUIRE_FALSE(ea);
  REQUIRE_FALSE(eb);
  CHECK(ea.error() == eb.error());

  // Other signals than the memo's (another dt, other data): not served from it.
  std::vector<double> t1b = t1;
  t1b[1500] += 1.0;
  const Signals other{t1b, t2, ta, 0.5};
  const auto oa = evaluate(*parse_term("d(T1)")->expr, other);
  const auto ob = evaluate(*parse_term("d(T1)")->expr, other, &memo);
  REQUIRE(oa);
  REQUIRE(ob);
  CHECK(*oa == *ob);
  CHECK(*ob != *d1);
  const Signals other_dt{t1, t2, ta, 1.0};
  CHECK(*evaluate(*parse_term("d(T1)")->expr, other_dt, &memo) == *evaluate(*parse_term("d(T1)")->expr, other_dt));
  CHECK(memo.computed() == 4);
}
