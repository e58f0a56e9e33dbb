// Step-1 statistics: each checked on a case whose answer is derived by hand in the comment.
#include <catch2/catch.hpp>
#include <cmath>
#include <random>

#include "fogbench/model/stats.hpp"

using namespace fogbench::model;

TEST_CASE("3-sigma rule drops only the sample beyond 3 sigma") {
  // 20 samples at +-1 around 0 plus one at 10: mean = 10/21 = 0.476, sample std with n-1:
  // sum of squares about the mean = 20*1 + 100 - 21*0.476^2 = 115.24, /20 -> sigma = 2.400.
  // |10 - 0.476| = 9.52 > 3*2.400 = 7.2, every +-1 sample is within 1.5.
  std::vector<double> x;
  for (int i = 0; i < 20; ++i) x.push_back(i % 2 ? 1.0 : -1.0);
  x.push_back(10.0);
  const auto r = outliers_3sigma(x);
  CHECK(r.removed == 1);
  CHECK_FALSE(r.keep.back());
  CHECK(r.mean == Approx(10.0 / 21.0));
  CHECK(r.sigma == Approx(std::sqrt((20.0 + 100.0 - 21.0 * (10.0 / 21.0) * (10.0 / 21.0)) / 20.0)));
}

TEST_CASE("AR(2) least squares recovers an exact recursion: Y(t) = -Y(t-2)") {
  // Y = 1, 0, -1, 0, 1, ... satisfies Y(t) = 0*Y(t-1) - 1*Y(t-2) exactly. The cross products
  // Y(t-1)Y(t-2) are all zero, so X'X is diagonal and k1 = 0, k2 = -1, residuals zero.
  std::vector<double> y;
  for (int t = 0; t < 40; ++t) y.push_back(t % 4 == 0 ? 1.0 : t % 4 == 2 ? -1.0 : 0.0);
  auto r = fit_ar(y, 2);
  REQUIRE(r);
  CHECK(r->k[0] == Approx(0.0).margin(1e-12));
  CHECK(r->k[1] == Approx(-1.0).epsilon(1e-12));
  CHECK(r->sigma_a2 == Approx(0.0).margin(1e-12));
}

TEST_CASE("AR(1) least squares and the paper's sigma_a^2 on a hand-computed series") {
  // Y repeats 1, 2, 0, 1 ten times (N = 40). Rows t = 2..40 pair Y(t) with Y(t-1):
  // within a block the products are 2*1, 0*2, 1*0 and across blocks 1*1: per block 2 + 1 = 3,
  // except the first block has no predecessor: sum Y(t)Y(t-1) = 10*2 + 9*1 = 29.
  // sum Y(t-1)^2 over t-1 = 1..39 = 10*(1+4+0+1) - 1 (the last Y(40) = 1 is not a regressor) = 59.
  // k1 = 29/59. Y'Y over t = 2..40 = 60 - 1 (Y(1) = 1 is not a target) = 59.
  // sigma_a^2 = (Y'Y - k1 * 29) / N = (59 - 29*29/59) / 40   (paper eq. 13 divides by N).
  std::vector<double> y;
  for (int b = 0; b < 10; ++b)
    for (double v : {1.0, 2.0, 0.0, 1.0}) y.push_back(v);
  auto r = fit_ar(y, 1);
  REQUIRE(r);
  CHECK(r->k[0] == Approx(29.0 / 59.0));
  CHECK(r->sigma_a2 == Approx((59.0 - 29.0 * 29.0 / 59.0) / 40.0));
}

TEST_CASE("AR(2) recovered from a long simulated series within its standard error") {
  // For AR(2) the asymptotic std of each estimate is sqrt((1 - k2^2)/N): with k2 = -0.4 and
  // N = 200000 that is 0.0020; 5 of them (0.010) is a tolerance that fails about once in 10^6.
  const double k1 = 0.5, k2 = -0.4, sigma = 0.146;
  std::mt19937_64 rng(42);
  std::normal_distribution<double> a(0.0, sigma);
  std::vector<double> y(200000, 0.0);
  for (std::size_t t = 2; t < y.size(); ++t) y[t] = k1 * y[t - 1] + k2 * y[t - 2] + a(rng);
  auto r = fit_ar(y, 2);
  REQUIRE(r);
  CHECK(r->k[0] == Approx(k1).margin(0.010));
  CHECK(r->k[1] == Approx(k2).margin(0.010));
  // sigma_a^2 has relative std sqrt(2/N) = 0.3%; allow 2%.
  CHECK(std::sqrt(r->sigma_a2) == Approx(sigma).epsilon(0.02));
  // Its residuals are white: Ljung-Box should not reject at 1%. (Fails 1% of seeds; 42 passes.)
  CHECK(whiteness(r->residuals, 20, 2).lb.p_value > 0.01);
}

TEST_CASE("AR fit refuses a series too short or constant") {
  std::vector<double> short_y(10, 1.0);
  CHECK_FALSE(fit_ar(short_y, 2));
  std::vector<double> flat(100, 0.0);
  auto r = fit_ar(flat, 2);
  REQUIRE_FALSE(r);
  CHECK(r.error().find("constant") != std::string::npos);
}

TEST_CASE("ACF and PACF of an exact AR(1) pattern, and the white band") {
  // x alternates +1, -1: r_k = (-1)^k (N-k)/N with the mean removed (mean 0 for even N).
  std::vector<double> x;
  for (int i = 0; i < 100; ++i) x.push_back(i % 2 ? -1.0 : 1.0);
  auto r = acf(x, 3);
  CHECK(r[0] == Approx(-99.0 / 100.0));
  CHECK(r[1] == Approx(98.0 / 100.0));
  auto p = pacf(x, 2);
  CHECK(p[0] == Approx(r[0]));  // phi_11 = r_1 by definition
  // phi_22 = (r2 - r1^2) / (1 - r1^2)
  CHECK(p[1] == Approx((r[1] - r[0] * r[0]) / (1.0 - r[0] * r[0])));
  CHECK(white_band(100) == Approx(0.2));
}

TEST_CASE("chi-square tail against tabulated values") {
  // Tabulated: P(chi2_1 > 3.841) = 0.05, P(chi2_10 > 18.307) = 0.05, P(chi2_2 > x) = exp(-x/2).
  CHECK(chi2_sf(3.841459, 1) == Approx(0.05).epsilon(1e-4));
  CHECK(chi2_sf(18.307038, 10) == Approx(0.05).epsilon(1e-4));
  CHECK(chi2_sf(5.0, 2) == Approx(std::exp(-2.5)).epsilon(1e-10));
  CHECK(chi2_sf(0.0, 3) == 1.0);
}

TEST_CASE("Ljung-Box rejects an autocorrelated series and its Q matches the formula") {
  // Alternating series: r_k = (-1)^k (N-k)/N; Q = N(N+2) sum r_k^2/(N-k) over k = 1..h.
  std::vector<double> x;
  for (int i = 0; i < 100; ++i) x.push_back(i % 2 ? -1.0 : 1.0);
  const auto lb = ljung_box(x, 5, 0);
  double q = 0.0;
  for (int k = 1; k <= 5; ++k) q += std::pow((100.0 - k) / 100.0, 2) / (100.0 - k);
  CHECK(lb.q == Approx(100.0 * 102.0 * q));
  CHECK(lb.dof == 5);
  CHECK(lb.p_value < 1e-10);
}

TEST_CASE("stationarity check: a variance burst is not stationary, white noise is") {
  std::mt19937_64 rng(7);
  std::normal_distribution<double> n(0.0, 1.0);
  std::vector<double> noise(6000), burst(6000);
  for (std::size_t i = 0; i < noise.size(); ++i) {
    noise[i] = n(rng);
    // The last of 10 sub-series has 3x the std: its gamma = mean + var is about 9 against
    // about 1 for the others; the mean gamma is (9*1 + 9)/10 = 1.8: m1 = 1, m2 = 9.
    burst[i] = (i >= 5400 ? 3.0 : 1.0) * n(rng);
  }
  const auto w = stationarity_check(noise);
  CHECK(w.stationary);
  const auto b = stationarity_check(burst);
  CHECK(b.m1 == 1);
  CHECK(b.m2 == 9);
  CHECK_FALSE(b.stationary);
}

TEST_CASE("moving_average: weighted, centred, shrunk at the ends, x itself where no weight") {
  const std::vector<double> x = {1, 2, 3, 4, 5}, w = {1, 1, 0, 1, 1};
  const std::vector<double> a = fogbench::model::moving_average(x, w, 3);
  REQUIRE(a.size() == 5);
  CHECK(a[0] == Approx(1.5));  // window {1, 2}
  CHECK(a[1] == Approx(1.5));  // {1, 2, (3 not counted)}
  CHECK(a[2] == Approx(3.0));  // {2, 4}
  CHECK(a[3] == Approx(4.5));  // {(3), 4, 5}
  CHECK(a[4] == Approx(4.5));  // {4, 5}
  const std::vector<double> none = fogbench::model::moving_average(std::vector<double>{7, 8}, std::vector<double>{0, 0}, 3);
  CHECK(none == std::vector<double>{7, 8});
  // Width 1 (or 0) is the identity on counted samples.
  CHECK(fogbench::model::moving_average(x, std::vector<double>(5, 1.0), 1) == x);
}

TEST_CASE("normal_quantile and confidence_band against tabulated z values") {
  // Tabulated: Phi^-1(0.975) = 1.959964, Phi^-1(0.995) = 2.575829, Phi^-1(0.5) = 0.
  CHECK(normal_quantile(0.975) == Approx(1.959964).margin(1e-6));
  CHECK(normal_quantile(0.995) == Approx(2.575829).margin(1e-6));
  CHECK(normal_quantile(0.5) == Approx(0.0).margin(1e-9));
  CHECK(normal_quantile(0.025) == Approx(-1.959964).margin(1e-6));
  CHECK(std::isnan(normal_quantile(0.0)));
  CHECK(std::isnan(normal_quantile(1.5)));
  // 99% on N = 10000: 2.575829 / 100.
  CHECK(confidence_band(10000, 0.99) == Approx(0.02575829).margin(1e-8));
  CHECK(std::isnan(confidence_band(0, 0.99)));
  CHECK(std::isnan(confidence_band(100, 1.0)));
}

TEST_CASE("ACF of white noise stays inside its 95% band at about 95% of lags, AR(1) at lag 1 is phi") {
  // White noise: each of 200 lags is inside +-1.96/sqrt(N) with probability 0.95, nearly
  // independently; the count of lags outside is about binomial(200, 0.05): mean 10, sd 3.1.
  // At most 22 outside (mean + 4 sd) keeps the test from failing by chance (it is seeded anyway).
  std::mt19937_64 rng(42);
  std::normal_distribution<double> g(0.0, 1.0);
  const std::size_t n = 20000;
  std::vector<double> w(n);
  for (double& v : w) v = g(rng);
  const std::vector<double> r = acf(w, 200);
  const double band = confidence_band(n, 0.95);
  int outside = 0;
  for (double v : r) outside += std::abs(v) > band;
  CHECK(outside <= 22);
  CHECK(outside >= 1);  // a band too wide would have none: P(0 of 200) = 0.95^200 = 3.5e-5
  // AR(1) with phi = 0.7: rho_1 = phi, rho_2 = phi^2; the sample ACF's sd at lag 1 is about
  // sqrt((1 - phi^2) / N) = 0.005, so 0.02 is 4 sd.
  std::vector<double> y(n);
  y[0] = g(rng);
  for (std::size_t t = 1; t < n; ++t) y[t] = 0.7 * y[t - 1] + g(rng);
  const std::vector<double> ry = acf(y, 2);
  CHECK(ry[0] == Approx(0.7).margin(0.02));
  CHECK(ry[1] == Approx(0.49).margin(0.03));
}

TEST_CASE("ccf: x leading a by d samples peaks at lag +d with r near 1, white pairs stay in the band") {
  // a_t = x_{t-5} + small noise: the CCF at lag k = +5 (x leading by 5) is
  // var(x) / sqrt(var(x) (var(x) + 0.1^2)) = 1 / sqrt(1.01) = 0.995.
  std::mt19937_64 rng(7);
  std::normal_distribution<double> g(0.0, 1.0);
  const std::size_t n = 5000;
  std::vector<double> x(n), a(n);
  for (double& v : x) v = g(rng);
  for (std::size_t t = 0; t < n; ++t) a[t] = (t >= 5 ? x[t - 5] : 0.0) + 0.1 * g(rng);
  const int L = 20;
  const std::vector<double> r = ccf(a, x, L);
  REQUIRE(r.size() == 2 * L + 1);
  std::size_t best = 0;
  for (std::size_t i = 0; i < r.size(); ++i)
    if (std::abs(r[i]) > std::abs(r[best])) best = i;
  CHECK(static_cast<int>(best) - L == 5);
  CHECK(r[best] == Approx(1.0 / std::sqrt(1.01)).margin(0.01));
  // Every other lag: two independent white series, inside the 99.9% band (3.29/sqrt(N)).
  const double band = confidence_band(n, 0.999);
  for (std::size_t i = 0; i < r.size(); ++i)
    if (i != best) CHECK(std::abs(r[i]) < band);
  // A series with itself at lag 0 is exactly 1; non-finite samples are left out, not spread.
  std::vector<double> xs = x;
  xs[100] = std::nan("");
  const std::vector<double> self = ccf(xs, xs, 0);
  CHECK(self[0] == Approx(1.0).margin(1e-3));
  CHECK(std::isfinite(self[0]));
  // A constant series correlates with nothing: zeros, not NaN.
  const std::vector<double> flat(n, 3.0);
  for (double v : ccf(flat, x, 3)) CHECK(v == 0.0);
}
