// check_collinear (model/src/fit_checks.cpp, internal to model/) on columns read at lags, as
// the refits of diagnose call it (a candidate at its own lag beside the model's terms): runs of
// any length modulo four (for a check whose sums are split into partial sums), lags that differ
// by column, and samples of weight zero holding NaN must give the verdict the columns call for.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "../../model/src/fit_internal.hpp"
#include "../../model/src/workbench_internal.hpp"

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

// mark_look_alikes (workbench_diagnose.cpp) takes each pair's two correlations from one pass
// (weighted_corr_pair) instead of two weighted_corr calls: they must be weighted_corr's numbers
// bit for bit in both orders (r(a, b) and r(b, a) round apart), also with weights of zero, a
// constant column and no weight at all.
TEST_CASE("weighted_corr_pair gives weighted_corr in both orders exactly") {
  using fogbench::model::workbench::wbi::corr_stats;
  using fogbench::model::workbench::wbi::weighted_corr;
  using fogbench::model::workbench::wbi::weighted_corr_pair;
  int differ = 0, pairs = 0;
  for (std::size_t n : {1u, 2u, 7u, 100u, 1001u, 20000u}) {
    for (unsigned seed = 1; seed <= 4; ++seed) {
      auto a = noise(n, seed), b = noise(n, seed + 100), w = noise(n, seed + 200);
      for (std::size_t t = 0; t < n; ++t) {
        b[t] += 0.9 * a[t] * (1.0 + 1e-3 * static_cast<double>(t % 7));  // correlated with a
        w[t] = t % 5 == 0 ? 0.0 : std::abs(w[t]);
      }
      std::vector<std::vector<double>> cols = {a, b, std::vector<double>(n, 2.5)};
      for (int zero_w = 0; zero_w < 2; ++zero_w) {
        const std::vector<double> ww = zero_w ? std::vector<double>(n, 0.0) : w;
        for (std::size_t i = 0; i < cols.size(); ++i)
          for (std::size_t j = 0; j < cols.size(); ++j) {
            const auto si = corr_stats(cols[i], ww), sj = corr_stats(cols[j], ww);
            const auto [rij, rji] = weighted_corr_pair(cols[i], si, cols[j], sj, ww);
            const double eij = weighted_corr(cols[i], cols[j], ww), eji = weighted_corr(cols[j], cols[i], ww);
            CHECK(std::memcmp(&rij, &eij, sizeof(double)) == 0);
            CHECK(std::memcmp(&rji, &eji, sizeof(double)) == 0);
            differ += eij != eji;
            ++pairs;
          }
      }
    }
  }
  // The two orders do round apart on some of these pairs: a pair that gave one number for both
  // would fail above.
  CHECK(differ > 0);
  CHECK(pairs == 6 * 4 * 2 * 9);
}

// find_jumps' thermal mask (mark_rate_changes, workbench_nonthermal.cpp) slides its window's
// minimum and maximum in O(n): the mask must be the one of the window scanned in full, as it
// was, on ramps and holds, noise near the threshold, windows cut at both ends, a run shorter
// than the window, marks already set, and NaN samples.
TEST_CASE("mark_rate_changes gives the full window scan's mask") {
  using fogbench::model::workbench::wbi::mark_rate_changes;
  auto reference = [](const std::vector<double>& rt, std::size_t half, double spread, std::vector<bool>& marked) {
    const std::size_t n = rt.size();
    for (std::size_t k = 0; k < n; ++k) {
      if (marked[k]) continue;
      const std::size_t lo = k >= half ? k - half : 0, hi = std::min(n - 1, k + half);
      double mn = rt[lo], mx = rt[lo];
      for (std::size_t u = lo; u <= hi; ++u) {
        mn = std::min(mn, rt[u]);
        mx = std::max(mx, rt[u]);
      }
      marked[k] = mx - mn > spread;
    }
  };
  int cases = 0, set_a = 0;
  for (std::size_t n : {1u, 2u, 5u, 150u, 301u, 302u, 1000u, 5000u}) {
    for (unsigned seed = 1; seed <= 3; ++seed) {
      auto rt = noise(n, seed);
      for (std::size_t t = 0; t < n; ++t) {
        rt[t] *= 0.04;                                     // noise of 0.04 degC/min about a rate
        if ((t / 400) % 3 == 1) rt[t] += 1.0;              // ramps of 1 degC/min between holds
        if (t % 97 == 3) rt[t] = rt[t > 0 ? t - 1 : 0];    // repeated values (ties in the queues)
      }
      for (int variant = 0; variant < 3; ++variant) {
        std::vector<double> x = rt;
        if (variant == 2 && n > 3) x[n / 2] = std::nan("");  // a gap
        for (std::size_t half : {1u, 10u, 150u}) {
          std::vector<bool> a(n, false), b(n, false);
          if (variant == 1)
            for (std::size_t t = 0; t < n; t += 7) a[t] = b[t] = true;  // marked by an earlier signal
          mark_rate_changes(x, half, 0.15, a);
          reference(x, half, 0.15, b);
          CHECK(a == b);
          for (bool v : a) set_a += v;
          ++cases;
        }
      }
    }
  }
  CHECK(cases == 8 * 3 * 3 * 3);
  CHECK(set_a > 0);
}
