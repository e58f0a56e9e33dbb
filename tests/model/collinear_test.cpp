// check_collinear (model/src/fit_checks.cpp, internal to model/) on columns read at lags, as
// the refits of diagnose call it (a candidate at its own lag beside the model's terms): runs of
// any length modulo four (for a check whose sums are split into partial sums), lags that differ
// by column, and samples of weight zero holding NaN must give the verdict the columns call for.
#include <catch2/catch.hpp>

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "../../model/src/fit_internal.hpp"

using namespace fogbench::model;
using namespace fogbench::model::detail;

namespace {

std::vector<double> noise(std::size_t n, unsigned seed) {
  std::mt19937 g(seed);
  std::normal_distribution<double> d(0.0, 1.0);
  std::vector<double> v(n);
  for (double& x : v) x = d(g);
  return v;
}

}  // namespace

TEST_CASE("check_collinear at lags: independent columns pass, a delayed combination is named") {
  {
    const std::size_t n = GENERATE(std::size_t{1003}, std::size_t{1004}, std::size_t{1005}, std::size_t{1006});
    INFO("n " << n);
    const std::vector<double> a = noise(n, 1), b = noise(n, 2);
    std::vector<double> w(n, 1.0);
    // c(t) = 2 a(t) - b(t - 5) (b's first value before the start, as the check reads it).
    std::vector<double> c(n);
    for (std::size_t t = 0; t < n; ++t) c[t] = 2.0 * a[t] - b[t >= 5 ? t - 5 : 0];
    const std::vector<std::string> names{"a", "b", "c"};
    const std::vector<std::size_t> at_5{0, 5, 0};
    const std::vector<std::size_t> at_6{0, 6, 0};
    SECTION("b read 5 samples late: c is a combination of a and b") {
      auto r = check_collinear({a, b, c}, names, w, at_5);
      REQUIRE_FALSE(r);
      CHECK(r.error().code == FitError::Code::collinear);
      CHECK_THAT(r.error().message, Catch::Contains("'a'") && Catch::Contains("'b'") && Catch::Contains("'c'"));
    }
    SECTION("b read 6 samples late: the three are independent") {
      CHECK(check_collinear({a, b, c}, names, w, at_6));
    }
    SECTION("a reading of weight zero holding NaN is not summed") {
      std::vector<double> a2 = a, w2 = w;
      a2[n - 1] = std::nan("");
      w2[n - 1] = 0.0;
      CHECK(check_collinear({a2, b, c}, names, w2, at_6));
      auto r = check_collinear({a2, b, c}, names, w2, at_5);
      REQUIRE_FALSE(r);
      CHECK(r.error().code == FitError::Code::collinear);
    }
    SECTION("a column constant where it has weight is named") {
      std::vector<double> k(n, 3.0);
      const std::vector<std::size_t> lags{0, 7};
      auto r = check_collinear({a, k}, {"a", "k"}, w, lags);
      REQUIRE_FALSE(r);
      CHECK_THAT(r.error().message, Catch::Contains("'k' is constant"));
    }
  }
}

TEST_CASE("check_collinear with a memo: sums kept by column and lag give the verdict computed afresh") {
  // diagnose's refits check the base's columns beside each candidate with one memo (the
  // FitCache's): a column's sums at one lag must never stand in for another lag's.
  const std::size_t n = 1005;
  const std::vector<double> a = noise(n, 1), b = noise(n, 2);
  std::vector<double> c(n);
  for (std::size_t t = 0; t < n; ++t) c[t] = 2.0 * a[t] - b[t >= 5 ? t - 5 : 0];
  const std::vector<double> w(n, 1.0);
  const std::vector<std::string> names{"a", "b", "c"};
  const std::vector<std::size_t> at_5{0, 5, 0}, at_6{0, 6, 0};
  const std::vector<std::string> keys_5{"a@0", "b@5", "c@0"}, keys_6{"a@0", "b@6", "c@0"};
  CollinearMemo memo;
  // Two columns first (another head: the longest lag is the same, the set is not).
  CHECK(check_collinear({a, b}, {"a", "b"}, w, std::vector<std::size_t>{0, 5}, &memo, std::vector<std::string>{"a@0", "b@5"}));
  CHECK(memo.mean.size() == 2);
  auto r5 = check_collinear({a, b, c}, names, w, at_5, &memo, keys_5);
  REQUIRE_FALSE(r5);
  CHECK(r5.error().code == FitError::Code::collinear);
  CHECK(check_collinear({a, b, c}, names, w, at_6, &memo, keys_6));
  CHECK_FALSE(check_collinear({a, b, c}, names, w, at_5, &memo, keys_5));
  // Keys that do not name every column: no memo (and no new entries).
  const std::size_t kept = memo.mean.size() + memo.cross.size();
  CHECK(check_collinear({a, b, c}, names, w, at_6, &memo, std::vector<std::string>{"a@0"}));
  CHECK(memo.mean.size() + memo.cross.size() == kept);
}
