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

// The product forms (wsum_product, spectrum_of_product, spectrum_of_lagged_product) make each
// product as the sums or the transform load it, instead of from an array of the products: the
// same multiplications and additions in the same order, so the numbers must be bit for bit
// those of the array forms (diagnose's output is compared byte for byte), on both of wsum's
// paths (few zeros: running sums; many: by FFT) and for a run shorter than its lags.
namespace {

void check_products_exact(std::size_t n, int max_lag, double zero_fraction, unsigned seed) {
  const Case c = make_case(n, zero_fraction, seed);
  const Case d = make_case(n, 0.0, seed + 100);
  LagScanner sc(n, max_lag, c.w);
  const Lagged lx = make_lagged(c.x, max_lag), ly = make_lagged(d.x, max_lag);
  std::vector<double> prod(lx.ext.size());
  for (std::size_t j = 0; j < prod.size(); ++j) prod[j] = lx.ext[j] * ly.ext[j];
  std::vector<double> by_array, by_product;
  sc.wsum(prod, by_array);
  sc.wsum_product(lx.ext, ly.ext, by_product);
  INFO("n " << n << ", max lag " << max_lag << ", zeros " << zero_fraction);
  CHECK(by_product == by_array);
  for (std::size_t lag : {std::size_t{0}, std::size_t{7}, static_cast<std::size_t>(max_lag)}) {
    std::vector<double> wx(n);
    for (std::size_t t = 0; t < n; ++t) wx[t] = c.w[t] * delayed(d.x, t, lag);
    Spectrum s_array, s_product;
    sc.spectrum_of_target(wx, s_array);
    if (lag == 0) sc.spectrum_of_product(c.w, d.x, s_product);
    else sc.spectrum_of_lagged_product(c.w, d.x, lag, s_product);
    INFO("lag " << lag);
    CHECK(s_product == s_array);
    // and what the scan reads from it: the correlation with a lagged regressor
    CHECK(sc.corr(lx, s_product) == sc.corr(lx, s_array));
  }
}

}  // namespace

TEST_CASE("lag scan: the product forms give the array forms' numbers exactly") {
  SECTION("few skipped samples (running sums)") { check_products_exact(40000, 600, 0.001, 7); }
  SECTION("many skipped samples (weights by FFT)") { check_products_exact(20000, 300, 0.3, 8); }
  SECTION("a run shorter than its lags") { check_products_exact(200, 300, 0.01, 9); }
  SECTION("a run shorter than one block") { check_products_exact(3000, 120, 0.0, 10); }
}
