// The operators' table (model/include/fogbench/model/term_ops.hpp), row by row: every operator
// parses and prints back, evaluates to a value computed by hand, has a firmware form that
// computes what predict() does (or is refused with the table's named error), and is generated
// by diagnose's search exactly when the table says so. A row added without a case here fails
// the test that asks for it. (The simulator's side: tests/sim/term_ops_sim_test.cpp.)
#include <catch2/catch.hpp>
#include <cmath>
#include <map>
#include <utility>
#include <string>

#include "fogbench/model/firmware.hpp"
#include "fogbench/model/term_ops.hpp"
#include "../../model/src/workbench_internal.hpp"

using namespace fogbench::model;

namespace {

bool contains(const Expr& e, Expr::Kind k) {
  return e.kind == k || (e.a && contains(*e.a, k)) || (e.b && contains(*e.b, k));
}

std::string kind_name(Expr::Kind k) { return std::string(term_op(k).name) + " (row " + std::to_string(static_cast<int>(k)) + ")"; }

// Hand-made signals, 200 samples at 1 s: T1 = 0.5 + 0.01 i + 0.0001 i^2 (a quadratic, so its
// centred least-squares slope is its exact derivative), T2 = -0.3 - 0.005 i, Ta a unit step at
// i = 10, ton = 100 + i s.
struct HandSignals {
  std::vector<double> t1, t2, ta, ton;
  HandSignals() {
    for (int i = 0; i < 200; ++i) {
      const double x = i;
      t1.push_back(0.5 + 0.01 * x + 0.0001 * x * x);
      t2.push_back(-0.3 - 0.005 * x);
      ta.push_back(i < 10 ? 0.0 : 1.0);
      ton.push_back(100.0 + x);
    }
  }
  Signals view() const { return Signals{t1, t2, ta, 1.0, ton}; }
};

// At sample 100: T1 = 2.5, dT1/dt = 0.03 degC/s = 1.8 degC/min, d2T1/dt2 = 0.72 degC/min^2,
// T2 = -0.8, T1[70] = 1.69, lp of the step after 91 samples at or after it: 1 - exp(-91/300).
struct HandCase {
  const char* text;
  double at_100;
};
const std::map<Expr::Kind, HandCase>& hand_cases() {
  using K = Expr::Kind;
  static const std::map<K, HandCase> cases = {
      {K::number, {"up(T1-0.5)", 2.0}},
      {K::signal, {"grad", 3.3}},
      {K::d, {"d(T1)", 1.8}},
      {K::dd, {"dd(T1)", 0.72}},
      {K::up, {"(up(T2)+up(T1))", 2.5}},
      {K::down, {"(down(T2)+down(T1))", -0.8}},
      {K::lp, {"lp(Ta,300)", 1.0 - std::exp(-91.0 / 300.0)}},
      {K::pow, {"T1^2", 6.25}},
      {K::mul, {"T1*T2", -2.0}},
      {K::add, {"(T1+T2)", 1.7}},
      {K::sub, {"(T1-T2)", 3.3}},
      {K::neg, {"up(-T2)", 0.8}},
      {K::delay, {"(T1@30)", 1.69}},
      {K::warm, {"warm(600)", std::exp(-200.0 / 600.0)}},
  };
  return cases;
}

// As tests/model/firmware_test.cpp: 3,000 s with holds and ramps, T2 lagging, Ta leading.
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

// The firmware form of `text` at the least lag it computes on time, against predict() once its
// windows hold real samples; the error when it is refused.
std::expected<double, std::string> firmware_vs_predict(const std::string& text) {
  auto t = parse_term(text);
  REQUIRE(t);
  Model m;
  m.mu0_dph = 1.25;
  FittedTerm f;
  f.term = *t;
  f.term.lag.seconds = firmware::causal_lag_s(*t->expr);
  f.coef = 0.5;
  m.terms.push_back(f);
  auto p = firmware::compile(m);
  if (!p) return std::unexpected(p.error());
  const RunData r = synthetic_run();
  auto mu = predict(m, r);
  REQUIRE(mu);
  firmware::Compensator c(*p);
  const auto from = static_cast<std::size_t>(firmware::warm_up_samples(*p) + f.term.lag.seconds + 2 * kDerivativeHalfWidth);
  double worst = 0.0;
  for (std::size_t i = 0; i < r.size(); ++i) {
    const double v = c.step({r.t1_c[i], r.t2_c[i], r.chamber_c[i], r.since_power_on_s[i]});
    if (i >= from) worst = std::max(worst, std::abs(v - (*mu)[i]));
  }
  return worst;
}

}  // namespace

TEST_CASE("term ops: one row per kind, in order, with a name and an example", "[terms][term_ops]") {
  REQUIRE(kTermOps.size() == kExprKinds);
  for (std::size_t i = 0; i < kTermOps.size(); ++i) {
    const TermOp& op = kTermOps[i];
    INFO(kind_name(op.kind));
    CHECK(static_cast<std::size_t>(op.kind) == i);
    CHECK_FALSE(op.name.empty());
    CHECK_FALSE(op.example.empty());
    CHECK_FALSE(op.firmware_form.empty());
    CHECK_FALSE(op.meaning.empty());
    CHECK((op.derivatives > 0) == (op.unit == OpUnit::rate));
  }
}

TEST_CASE("term ops: every operator's example parses, holds the operator and prints back the same", "[terms][term_ops]") {
  for (const TermOp& op : kTermOps) {
    INFO(kind_name(op.kind) << " example " << op.example);
    auto t = parse_term(op.example);
    REQUIRE(t);
    CHECK(contains(*t->expr, op.kind));
    CHECK(to_string(*t) == op.example);
    auto again = parse_term(to_string(*t));
    REQUIRE(again);
    CHECK(to_string(*again) == op.example);
  }
  for (const TermSignal& s : kTermSignals) {
    auto t = parse_term(s.name);
    REQUIRE(t);
    CHECK(t->expr->kind == Expr::Kind::signal);
    CHECK(t->expr->signal == s.signal);
    CHECK(to_string(*t) == s.name);
  }
}

TEST_CASE("term ops: the parser's messages name every function and signal of the tables", "[terms][term_ops]") {
  auto e = parse_term("foo(T1)");
  REQUIRE_FALSE(e);
  CHECK(e.error().message ==
        "unknown name 'foo': expected a signal (T1, T2, Ta, grad, ton, trun, T1x, T2x, T1y, T2y, T1z, T2z) or a function (d, dd, up, down, lp, warm)");
  for (const TermOp& op : kTermOps)
    if (op.syntax == OpSyntax::call || op.syntax == OpSyntax::call_tau || op.syntax == OpSyntax::tau_only)
      CHECK(function_names().find(op.name) != std::string::npos);
}

TEST_CASE("term ops: every operator evaluates to the value computed by hand", "[terms][term_ops]") {
  const HandSignals h;
  for (const TermOp& op : kTermOps) {
    INFO(kind_name(op.kind));
    const auto it = hand_cases().find(op.kind);
    REQUIRE(it != hand_cases().end());  // a new operator needs its hand-computed case above
    INFO(it->second.text);
    auto t = parse_term(it->second.text);
    REQUIRE(t);
    CHECK(contains(*t->expr, op.kind));
    auto v = evaluate(*t->expr, h.view());
    REQUIRE(v);
    CHECK((*v)[100] * t->coef == Approx(it->second.at_100).margin(1e-9));
  }
}

TEST_CASE("term ops: the firmware computes every operator as predict does, or refuses it naming why", "[terms][term_ops][firmware]") {
  for (const TermOp& op : kTermOps) {
    INFO(kind_name(op.kind) << " example " << op.example);
    auto worst = firmware_vs_predict(std::string(op.example));
    if (op.firmware == OpFirmware::refused) {
      REQUIRE_FALSE(worst);
      CHECK(worst.error().find(op.firmware_form) != std::string::npos);
    } else {
      INFO((worst ? std::string() : worst.error()));
      REQUIRE(worst);
      CHECK(*worst < 1e-9);
    }
  }
  for (const TermSignal& s : kTermSignals) {
    INFO(s.name);
    auto worst = firmware_vs_predict(std::string(s.name));
    if (s.firmware_input == -1) {
      REQUIRE_FALSE(worst);
      CHECK(worst.error() == "term " + std::string(s.name) + ": " + std::string(s.firmware_refusal));
    } else {
      REQUIRE(worst);
      CHECK(*worst < 1e-9);
    }
  }
}

TEST_CASE("term ops: diagnose's search generates exactly the operators the table marks searched", "[terms][term_ops][workbench]") {
  const auto exprs = workbench::wbi::search_expressions(workbench::DiagnoseOptions{}, true, true);
  REQUIRE(exprs.size() > 100);
  for (const TermOp& op : kTermOps) {
    INFO(kind_name(op.kind));
    bool found = false;
    for (const auto& g : exprs) {
      const std::string& text = g.expr;
      auto t = parse_term(text);
      REQUIRE(t);
      CHECK(to_string(*t->expr) == text);  // generated in canonical spelling
      found = found || contains(*t->expr, op.kind);
    }
    CHECK(found == op.searched);
  }
}

TEST_CASE("term ops: diagnose names a generated candidate outside the library by its outermost operator", "[terms][term_ops][workbench]") {
  std::map<std::string, workbench::wbi::Generated> by_expr;
  for (const auto& g : workbench::wbi::search_expressions(workbench::DiagnoseOptions{}, true, true)) by_expr[g.expr] = g;
  const std::pair<const char*, const char*> names[] = {
      {"warm(300)", "warm-up after power-on (exp(-ton/tau), tau 300 s)"},
      {"ton", "drift with the time since power-on (aging of the source, slow warm-up)"},
      {"lp(T2,90)", "a slow thermal path (lp(T2,90))"},
      {"d(lp(Ta,160))", "rate through a slow thermal path (lp(Ta,160))"},
      {"T1*d(T2)", "a product of two signals (T1*d(T2)), not in the library"},
      {"grad^3", "a nonlinear power (grad^3), not in the library"},
      {"up(d(T2))", "an effect outside the library (up(d(T2)))"},
      {"d(T1)", "Shupe effect (rate of the coil temperature)"},
  };
  for (const auto& [expr, name] : names) {
    INFO(expr);
    REQUIRE(by_expr.count(expr) == 1);
    CHECK(by_expr[expr].effect == name);
  }
  CHECK(by_expr["warm(300)"].explanation.find("warm up after power-on") != std::string::npos);
  CHECK(by_expr["lp(T2,90)"].explanation.find("slower path") != std::string::npos);
  CHECK(by_expr["d(lp(Ta,160))"].explanation == by_expr["lp(T2,90)"].explanation);
  CHECK(by_expr["T1*d(T2)"].explanation == "found by the search over the term language; no physical name is attached to it");
}

TEST_CASE("term signals: an axis's own coil thermistors T1x..T2z, read where recorded and named where not", "[terms][cross_axis]") {
  const std::vector<double> t1 = {1, 2, 3}, t2 = {0, 1, 2}, y1 = {5, 6, 7}, y2 = {4, 5, 6}, z1 = {8, 9, 10}, z2 = {7, 8, 9};
  Signals s{t1, t2, {}, 1.0};
  auto e = parse_terms("T1y + T2z");
  REQUIRE(e);
  // Without per-axis thermistors: the error names the signal and the columns.
  auto none = evaluate(*e->terms[0].expr, s);
  REQUIRE_FALSE(none);
  CHECK_THAT(none.error(), Catch::Contains("T1y") && Catch::Contains("t1_y_c"));
  s.axis_t1 = {t1, y1, z1};
  s.axis_t2 = {t2, y2, z2};
  CHECK(*evaluate(*e->terms[0].expr, s) == y1);
  CHECK(*evaluate(*e->terms[1].expr, s) == z2);
  CHECK(uses_axis_thermistor(*e->terms[0].expr));
  CHECK_FALSE(uses_axis_thermistor(*parse_terms("d(T1)")->terms[0].expr));
  CHECK(coef_unit(*e->terms[0].expr) == "deg/h per degC");
  // The firmware form has one axis's inputs: refused with the table's reason.
  const auto fw = firmware_vs_predict("T1y");
  REQUIRE_FALSE(fw);
  CHECK_THAT(fw.error(), Catch::Contains("cross-axis"));
}
