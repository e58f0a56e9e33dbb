// The lag scan's sums (model/src/lagscan.hpp, internal to model/) against the same sums taken
// directly, lag by lag: the FFT blocks must reproduce them for runs shorter than one block,
// runs of many blocks with a ragged last one, and weights with few or many zeros.
#include <catch2/catch.hpp>

#include <cmath>
#include <random>
#include <vector>

#include "../../model/src/lagscan.hpp"

using namespace fogbench::model::detail;

namespace {

struct Case {
  std::vector<double> x, u, w;
};

Case make_case(std::size_t n, double zero_fraction, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  std::uniform_real_distribution<double> p(0.0, 1.0);
  Case c;
  double level = 20.0;
  for (std::size_t t = 0; t < n; ++t) {
    level += 0.05 * g(rng);           // a wandering temperature-like series
    c.x.push_back(level);
    c.u.push_back(g(rng) + 0.1 * level);
    c.w.push_back(p(rng) < zero_fraction ? 0.0 : 1.0);
  }
  return c;
}

// x(t - i) with the first value standing in before the start, as make_lagged extends it.
double delayed(const std::vector<double>& x, std::size_t t, std::size_t i) { return x[t >= i ? t - i : 0]; }

void check_against_direct(std::size_t n, int max_lag, double zero_fraction, unsigned seed) {
  const Case c = make_case(n, zero_fraction, seed);
  LagScanner sc(n, max_lag, c.w);
  const Lagged lx = make_lagged(c.x, max_lag);
  std::vector<double> wu(n);
  for (std::size_t t = 0; t < n; ++t) wu[t] = c.w[t] * c.u[t];
  const std::vector<double> cross = sc.corr(lx, wu);
  const std::vector<double> sums = sc.wsum(lx.ext);
  std::vector<double> sq_ext(lx.ext.size());
  for (std::size_t j = 0; j < sq_ext.size(); ++j) sq_ext[j] = lx.ext[j] * lx.ext[j];
  const std::vector<double> squares = sc.wsum(sq_ext);
  REQUIRE(cross.size() == static_cast<std::size_t>(max_lag) + 1);
  for (int i = 0; i <= max_lag; ++i) {
    double want_cross = 0, want_sum = 0, want_sq = 0, scale = 0;
    for (std::size_t t = 0; t < n; ++t) {
      const double xd = delayed(c.x, t, static_cast<std::size_t>(i));
      want_cross += wu[t] * xd;
      want_sum += c.w[t] * xd;
      want_sq += c.w[t] * xd * xd;
      scale += std::abs(wu[t] * xd);
    }
    INFO("n " << n << ", lag " << i << " of " << max_lag << ", zeros " << zero_fraction);
    // FFT round-off grows like log(m) eps times the sum of magnitudes; 1e-11 of it is generous
    // and still 1e5 times smaller than any wrong term would make it.
    CHECK(std::abs(cross[static_cast<std::size_t>(i)] - want_cross) <= 1e-11 * scale + 1e-12);
    CHECK(std::abs(sums[static_cast<std::size_t>(i)] - want_sum) <= 1e-11 * std::abs(want_sum) + 1e-9);
    CHECK(std::abs(squares[static_cast<std::size_t>(i)] - want_sq) <= 1e-11 * std::abs(want_sq) + 1e-9);
  }
}

}  // namespace

TEST_CASE("lag scan: sums for every lag equal the direct sums") {
  SECTION("a run shorter than one block") { check_against_direct(3000, 120, 0.01, 1); }
  SECTION("many blocks, the last one ragged, few skipped samples") { check_against_direct(40000, 600, 0.001, 2); }
  SECTION("many blocks with many skipped samples (weights by FFT)") { check_against_direct(20000, 300, 0.3, 3); }
  SECTION("a run exactly one block step long, and lag 0 only") {
    check_against_direct(8192 - 600, 600, 0.0, 4);
    check_against_direct(9000, 0, 0.0, 5);
  }
  SECTION("a long maximum lag makes a larger block") { check_against_direct(30000, 3000, 0.0, 6); }
}
