// One axis of a three-axis unit as the drift analysis reads it: select_axis, the model's axis in
// its JSON, verify refusing another axis's output, and per-axis fits recovering each axis's own
// drift from one recording.
#include <catch2/catch.hpp>
#include <array>
#include <cmath>
#include <random>

#include "fogbench/model/json.hpp"
#include "fogbench/model/model.hpp"

using namespace fogbench::model;

namespace {

// A three-axis recording of n s: 600 s hold at 20 degC, then T1 a sum of two sines (+-8 and
// +-2 degC), T2 leading it. Every axis has mu0 -8 deg/h and -3 deg/h per degC/min of d(T1)
// at lag 38 s; each adds its own t1_coef[k] * (T1 - 20 degC) and white noise 0.15 deg/h
// (independent per axis).
RunData three_axis_recording(std::size_t n, std::array<double, 3> t1_coef, unsigned seed) {
  RunData r;
  r.name = "three-axis";
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> e(0.0, 0.15);
  for (std::size_t i = 0; i < n; ++i) {
    const double u = i < 600 ? 0.0 : static_cast<double>(i) - 600.0;
    r.time_s.push_back(static_cast<double>(i));
    r.t1_c.push_back(20.0 + 8.0 * std::sin(2 * M_PI * u / 3000.0) + 2.0 * std::sin(2 * M_PI * u / 1100.0));
    r.t2_c.push_back(20.0 + 8.0 * std::sin(2 * M_PI * (u + 60) / 3000.0) + 2.0 * std::sin(2 * M_PI * (u + 40) / 1100.0) * (u > 0));
  }
  std::vector<double> t1(n);
  for (std::size_t i = 0; i < n; ++i) t1[i] = r.t1_c[i] - 20.0;
  const auto d = derivative_per_min(t1, 1.0);
  for (std::vector<double>* axis : {&r.gyro_dph, &r.gyro_y_dph, &r.gyro_z_dph}) {
    const double c = t1_coef[static_cast<std::size_t>(axis == &r.gyro_dph ? 0 : axis == &r.gyro_y_dph ? 1 : 2)];
    for (std::size_t i = 0; i < n; ++i) axis->push_back(-8.0 - 3.0 * d[i >= 38 ? i - 38 : 0] + c * t1[i] + e(rng));
  }
  return r;
}

}  // namespace

TEST_CASE("axes: names x, y, z and back, nothing else", "[axes]") {
  for (Axis a : {Axis::x, Axis::y, Axis::z}) CHECK(axis_from_string(to_string(a)) == a);
  CHECK(to_string(Axis::y) == "y");
  CHECK_FALSE(axis_from_string("X").has_value());
  CHECK_FALSE(axis_from_string("w").has_value());
  CHECK_FALSE(axis_from_string("").has_value());
}

TEST_CASE("axes: select_axis makes gyro_dph the asked axis and drops the others", "[axes]") {
  RunData r;
  r.name = "u.csv";
  r.time_s = {0, 1, 2};
  r.t1_c = r.t2_c = {20, 20, 20};
  r.gyro_dph = {1, 2, 3};
  r.gyro_y_dph = {10, 20, 30};
  r.gyro_z_dph = {100, 200, 300};
  r.compensated_dph = {0.1, 0.2, 0.3};

  auto y = select_axis(r, Axis::y);
  REQUIRE(y);
  CHECK(y->gyro_dph == std::vector<double>{10, 20, 30});
  CHECK(y->axis == Axis::y);
  CHECK(y->gyro_axis() == Axis::y);
  CHECK_FALSE(y->has_axes());
  CHECK_FALSE(y->has_compensated());  // the live compensation is x's
  auto z = select_axis(r, Axis::z);
  REQUIRE(z);
  CHECK(z->gyro_dph == std::vector<double>{100, 200, 300});
  auto x = select_axis(r, Axis::x);
  REQUIRE(x);
  CHECK(x->gyro_dph == std::vector<double>{1, 2, 3});
  CHECK(x->axis == Axis::x);
  CHECK(x->compensated_dph == r.compensated_dph);

  // Picked once: the same axis again is the same run, another is refused.
  CHECK(select_axis(*y, Axis::y).has_value());
  auto again = select_axis(*y, Axis::z);
  REQUIRE_FALSE(again);
  CHECK_THAT(again.error(), Catch::Contains("u.csv") && Catch::Contains("axis z") && Catch::Contains("holds axis y"));

  // A one-axis run: x is itself, y and z are refused naming the run and the axis.
  RunData one = r;
  one.gyro_y_dph.clear();
  one.gyro_z_dph.clear();
  auto ox = select_axis(one, Axis::x);
  REQUIRE(ox);
  CHECK_FALSE(ox->axis.has_value());
  CHECK(ox->gyro_dph == one.gyro_dph);
  auto oy = select_axis(one, Axis::y);
  REQUIRE_FALSE(oy);
  CHECK_THAT(oy.error(), Catch::Contains("u.csv") && Catch::Contains("axis y") && Catch::Contains("one-axis"));
}

TEST_CASE("axes: each axis's fit recovers that axis's own drift, and the model records its axis", "[axes]") {
  // x has no T1 sensitivity, y 0.05 and z -0.03 deg/h per degC. As fit_test.cpp's two-term
  // case (same signals, length and noise, whose margins these are), the T1 coefficient is
  // determined to about 1e-3 (0.005 is about 5 se) and d(T1)'s to about 0.002 (0.03 is 1 %).
  const RunData rec = three_axis_recording(20000, {0.0, 0.05, -0.03}, 5);
  FitOptions o;
  o.method = Method::joint;
  const auto terms = parse_terms("d(T1)@auto + T1");
  REQUIRE(terms);
  const std::array<double, 3> truth = {0.0, 0.05, -0.03};
  for (Axis a : {Axis::x, Axis::y, Axis::z}) {
    INFO("axis " << to_string(a));
    auto run = select_axis(rec, a);
    REQUIRE(run);
    auto m = fit(*run, *terms, o);
    REQUIRE(m);
    CHECK(m->axis == a);
    CHECK(m->mu0_dph == Approx(-8.0).margin(0.02));
    CHECK(m->terms[0].coef == Approx(-3.0).margin(0.03));
    CHECK(m->terms[1].coef == Approx(truth[static_cast<std::size_t>(a)]).margin(0.005));
    const auto j = to_json(*m);
    CHECK(j.at("axis") == std::string(to_string(a)));
    auto back = model_from_json(j);
    REQUIRE(back);
    CHECK(back->axis == a);
  }
  // A one-axis run's model has no axis, in memory and in JSON.
  RunData one = rec;
  one.gyro_y_dph.clear();
  one.gyro_z_dph.clear();
  auto m1 = fit(one, *terms, o);
  REQUIRE(m1);
  CHECK_FALSE(m1->axis.has_value());
  CHECK_FALSE(to_json(*m1).contains("axis"));
}

TEST_CASE("axes: verify refuses a run of another axis than the model's, and a bad axis in JSON", "[axes]") {
  const RunData rec = three_axis_recording(8000, {0.0, 0.05, 0.0}, 6);
  FitOptions o;
  o.method = Method::joint;
  const auto terms = parse_terms("d(T1)@auto");
  auto y = select_axis(rec, Axis::y);
  REQUIRE(y);
  auto my = fit(*y, *terms, o);
  REQUIRE(my);
  CHECK(verify(*my, *y).has_value());
  // The same recording unpicked is its x: refused, naming both axes.
  auto wrong = verify(*my, rec);
  REQUIRE_FALSE(wrong);
  CHECK_THAT(wrong.error().message, Catch::Contains("fitted on axis y") && Catch::Contains("holds axis x"));
  // A model without an axis is x's: a picked y is refused, a picked x is its own.
  RunData one = rec;
  one.gyro_y_dph.clear();
  one.gyro_z_dph.clear();
  auto mx = fit(one, *terms, o);
  REQUIRE(mx);
  CHECK_FALSE(verify(*mx, *y).has_value());
  CHECK(verify(*mx, *select_axis(rec, Axis::x)).has_value());

  auto j = to_json(*my);
  j["axis"] = "w";
  auto bad = model_from_json(j);
  REQUIRE_FALSE(bad);
  CHECK_THAT(bad.error(), Catch::Contains("axis") && Catch::Contains("\"w\""));
  j["axis"] = 1;
  CHECK_FALSE(model_from_json(j).has_value());
}
