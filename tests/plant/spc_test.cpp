// The fleet statistics (plant/spc.hpp) against values worked by hand.
#include <catch2/catch.hpp>

#include <cmath>

#include "fogbench/plant/spc.hpp"

using namespace fogbench::plant::spc;

namespace {
bool has(const std::vector<Signal>& s, Rule r, std::size_t index) {
  for (const auto& x : s)
    if (x.rule == r && x.index == index) return true;
  return false;
}
std::size_t count(const std::vector<Signal>& s, Rule r) {
  std::size_t n = 0;
  for (const auto& x : s) n += x.rule == r;
  return n;
}
}  // namespace

TEST_CASE("spc: the individuals and moving-range chart's limits by hand") {
  const std::vector<double> x = {10, 12, 11, 13, 12};
  const auto c = imr_chart(x, 0, x.size());
  // mean 58/5 = 11.6; moving ranges 2, 1, 2, 1: MRbar 1.5; sigma 1.5/1.128.
  CHECK(c.center == Approx(11.6));
  CHECK(c.mr_bar == Approx(1.5));
  CHECK(c.sigma == Approx(1.5 / 1.128));
  CHECK(c.ucl == Approx(11.6 + 3 * 1.5 / 1.128));
  CHECK(c.lcl == Approx(11.6 - 3 * 1.5 / 1.128));
  CHECK(c.mr_ucl == Approx(3.267 * 1.5));
  CHECK(std::isnan(c.mr[0]));
  CHECK(c.mr[3] == 2);
  CHECK(c.signals.empty());
  // Limits from a window: the first three only (mean 11, MRs 2 and 1).
  const auto w = imr_chart(x, 0, 3);
  CHECK(w.center == Approx(11.0));
  CHECK(w.mr_bar == Approx(1.5));
  CHECK_THROWS_AS(imr_chart(x, 4, 5), std::invalid_argument);
  CHECK_THROWS_AS(imr_chart(x, 0, 6), std::invalid_argument);
}

TEST_CASE("spc: each Western Electric rule fires where its pattern completes, and not on near misses") {
  // Rule 1: beyond 3 sigma, either side; 3 exactly is not beyond.
  auto s = western_electric(std::vector<double>{0.5, 3.5, 3.0, -3.2}, 0, 1);
  CHECK(has(s, Rule::beyond_3_sigma, 1));
  CHECK_FALSE(has(s, Rule::beyond_3_sigma, 2));
  CHECK(has(s, Rule::beyond_3_sigma, 3));
  // Rule 2: two of three beyond 2 sigma on the same side; opposite sides do not count.
  s = western_electric(std::vector<double>{2.5, 0, 2.5}, 0, 1);
  CHECK(has(s, Rule::two_of_three, 2));
  CHECK(count(western_electric(std::vector<double>{2.5, 0, -2.5}, 0, 1), Rule::two_of_three) == 0);
  CHECK(count(western_electric(std::vector<double>{2.5, 0, 0, 2.5}, 0, 1), Rule::two_of_three) == 0);
  // Rule 3: four of five beyond 1 sigma on the same side (three of five do not).
  s = western_electric(std::vector<double>{-1.5, -1.5, 0, -1.5, -1.5}, 0, 1);
  CHECK(has(s, Rule::four_of_five, 4));
  CHECK(count(western_electric(std::vector<double>{1.5, 0, 0, 1.5, 1.5}, 0, 1), Rule::four_of_five) == 0);
  // Rule 4: eight in a row on one side; seven do not.
  std::vector<double> eight(8, 0.5), seven(7, 0.5);
  CHECK(has(western_electric(eight, 0, 1), Rule::eight_one_side, 7));
  CHECK(count(western_electric(seven, 0, 1), Rule::eight_one_side) == 0);
  // A moving range above D4 MRbar is a signal on the MR chart.
  const std::vector<double> x = {0, 1, 0, 1, 0, 1, 0, 9, 0};
  const auto c = imr_chart(x, 0, 7);  // MRbar 1 in the window
  CHECK(has(c.signals, Rule::moving_range, 7));
  CHECK(has(c.signals, Rule::moving_range, 8));
  CHECK(has(c.signals, Rule::beyond_3_sigma, 7));
}

TEST_CASE("spc: Student's t quantiles and Welch's interval by hand") {
  CHECK(student_t_quantile(0.975, 10) == Approx(2.228138852).epsilon(1e-8));
  CHECK(student_t_quantile(0.995, 3) == Approx(5.840909310).epsilon(1e-8));
  CHECK(student_t_cdf(0, 5) == Approx(0.5));
  // a = 1..5 (mean 3, var 2.5), b = 2,4..12 (mean 7, var 14): se^2 = 2.5/5 + 14/6,
  // dof = (se^2)^2 / (0.5^2/4 + (14/6)^2/5) = 6.97226; t(0.975, 6.97226) = 2.36653 (integrated
  // numerically, independently of the incomplete beta used here).
  const std::vector<double> a = {1, 2, 3, 4, 5}, b = {2, 4, 6, 8, 10, 12};
  const auto w = welch(a, b);
  CHECK(w.diff == Approx(-4));
  CHECK(w.se == Approx(1.6832508231));
  CHECK(w.dof == Approx(6.9722557298));
  CHECK(w.t_crit == Approx(2.3665330449).epsilon(1e-7));
  CHECK(w.low == Approx(-7.9834686956).epsilon(1e-7));
  CHECK(w.high == Approx(-0.0165313044).epsilon(1e-5));
  CHECK(w.p_value == Approx(0.0492843382).epsilon(1e-6));
  CHECK_THROWS_AS(welch(std::vector<double>{1}, b), std::invalid_argument);
  const auto s = summarize(b);
  CHECK(s.median == Approx(7));
  CHECK(s.sd == Approx(std::sqrt(14.0)));
}
