// Step-1 statistics of the paper: outliers, stationarity, AR(p), ACF/PACF, Ljung-Box.
#include "fogbench/model/stats.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>
#include <numeric>

namespace fogbench::model {

double mean(std::span<const double> x) {
  if (x.empty()) return 0.0;
  return std::accumulate(x.begin(), x.end(), 0.0) / static_cast<double>(x.size());
}

double stddev(std::span<const double> x) {
  if (x.size() < 2) return 0.0;
  const double m = mean(x);
  double ss = 0.0;
  for (double v : x) ss += (v - m) * (v - m);
  return std::sqrt(ss / static_cast<double>(x.size() - 1));
}

OutlierResult outliers_3sigma(std::span<const double> x, double k_sigma) {
  OutlierResult r;
  r.keep.assign(x.size(), true);
  r.mean = mean(x);
  r.sigma = stddev(x);
  if (r.sigma <= 0.0) return r;
  for (std::size_t i = 0; i < x.size(); ++i) {
    if (std::abs(x[i] - r.mean) > k_sigma * r.sigma) {
      r.keep[i] = false;
      ++r.removed;
    }
  }
  return r;
}

StationarityResult stationarity_check(std::span<const double> y, int m) {
  StationarityResult r;
  r.m = m;
  if (m < 2 || y.size() < static_cast<std::size_t>(2 * m)) return r;
  const std::size_t len = y.size() / static_cast<std::size_t>(m);
  for (int i = 0; i < m; ++i) {
    auto sub = y.subspan(static_cast<std::size_t>(i) * len, len);
    const double mu = mean(sub);
    double var = 0.0;
    for (double v : sub) var += (v - mu) * (v - mu);
    var /= static_cast<double>(len);
    r.gamma.push_back(mu + var);
  }
  const double gbar = mean(r.gamma);
  for (double g : r.gamma) (g > gbar ? r.m1 : r.m2)++;
  r.stationary = 10 * std::abs(r.m1 - r.m2) <= 6 * m;
  return r;
}

std::expected<ArFit, std::string> fit_ar(std::span<const double> y, int p) {
  if (p < 1) return std::unexpected("AR order must be at least 1, got " + std::to_string(p));
  const auto n = static_cast<Eigen::Index>(y.size());
  // N >> p keeps X'X non-singular (paper, after eq. 12); ask for at least 10 rows per coefficient.
  if (n < p + 10 * p)
    return std::unexpected("AR(" + std::to_string(p) + ") needs at least " + std::to_string(11 * p) +
                           " samples, got " + std::to_string(n));
  const Eigen::Index rows = n - p;
  Eigen::MatrixXd X(rows, p);
  Eigen::VectorXd Y(rows);
  for (Eigen::Index t = p; t < n; ++t) {
    Y(t - p) = y[static_cast<std::size_t>(t)];
    for (int j = 0; j < p; ++j) X(t - p, j) = y[static_cast<std::size_t>(t - 1 - j)];
  }
  const Eigen::MatrixXd XtX = X.transpose() * X;
  Eigen::LDLT<Eigen::MatrixXd> ldlt(XtX);
  if (ldlt.info() != Eigen::Success || ldlt.rcond() < 1e-12)
    return std::unexpected("AR fit: the series is constant or degenerate (X'X is singular)");
  const Eigen::VectorXd XtY = X.transpose() * Y;
  const Eigen::VectorXd theta = ldlt.solve(XtY);
  ArFit r;
  r.k.assign(theta.data(), theta.data() + p);
  r.sigma_a2 = std::max(0.0, (Y.dot(Y) - XtY.dot(theta)) / static_cast<double>(n));
  const Eigen::VectorXd a = Y - X * theta;
  r.residuals.assign(a.data(), a.data() + rows);
  return r;
}

void ar_filter(std::span<const double> x, std::span<const double> k, std::vector<double>& out) {
  out.resize(x.size());
  const std::size_t p = k.size(), n = x.size();
  const std::size_t head = std::min(p, n);
  for (std::size_t t = 0; t < head; ++t) {  // the start: earlier samples equal x[0]
    double v = x[t];
    for (std::size_t j = 0; j < p; ++j) v -= k[j] * (t >= j + 1 ? x[t - j - 1] : x[0]);
    out[t] = v;
  }
  if (p == 2) {  // the common case, unrolled
    const double k1 = k[0], k2 = k[1];
    for (std::size_t t = head; t < n; ++t) out[t] = x[t] - k1 * x[t - 1] - k2 * x[t - 2];
    return;
  }
  for (std::size_t t = head; t < n; ++t) {
    double v = x[t];
    for (std::size_t j = 0; j < p; ++j) v -= k[j] * x[t - j - 1];
    out[t] = v;
  }
}

std::vector<double> ar_filter(std::span<const double> x, std::span<const double> k) {
  std::vector<double> out;
  ar_filter(x, k, out);
  return out;
}

namespace {

// acf's sums with the deviations from the mean formed once (the same values, in the same
// order, as forming them in each product: whiteness reads the ACF of long runs many times).
std::vector<double> acf_of(std::span<const double> x, int max_lag) {
  std::vector<double> r;
  const std::size_t n = x.size();
  if (n < 2 || max_lag < 1) return r;
  const double m = mean(x);
  std::vector<double> d(n);
  for (std::size_t t = 0; t < n; ++t) d[t] = x[t] - m;
  double c0 = 0.0;
  for (double v : d) c0 += v * v;
  const int h = std::min<int>(max_lag, static_cast<int>(n) - 1);
  r.reserve(static_cast<std::size_t>(h));
  for (int k = 1; k <= h; ++k) {
    double c = 0.0;
    const std::size_t ku = static_cast<std::size_t>(k);
    for (std::size_t t = 0; t + ku < n; ++t) c += d[t] * d[t + ku];
    r.push_back(c0 > 0.0 ? c / c0 : 0.0);
  }
  return r;
}

// Durbin-Levinson on an ACF r[0..h-1] (lags 1..h).
std::vector<double> pacf_of_acf(const std::vector<double>& r) {
  const std::size_t h = r.size();
  std::vector<double> out(h), phi(h + 1, 0.0), prev(h + 1, 0.0);
  double v = 1.0;
  for (std::size_t k = 1; k <= h; ++k) {
    double num = r[k - 1];
    for (std::size_t j = 1; j < k; ++j) num -= prev[j] * r[k - j - 1];
    const double pk = v > 0.0 ? num / v : 0.0;
    phi[k] = pk;
    for (std::size_t j = 1; j < k; ++j) phi[j] = prev[j] - pk * prev[k - j];
    v *= (1.0 - pk * pk);
    out[k - 1] = pk;
    prev = phi;
  }
  return out;
}

LjungBox ljung_box_of_acf(const std::vector<double>& r, std::size_t n_samples, int fitted_params) {
  LjungBox lb;
  const auto n = static_cast<double>(n_samples);
  lb.lags = static_cast<int>(r.size());
  lb.dof = std::max(1, lb.lags - fitted_params);
  for (std::size_t k = 1; k <= r.size(); ++k) lb.q += r[k - 1] * r[k - 1] / (n - static_cast<double>(k));
  lb.q *= n * (n + 2.0);
  lb.p_value = chi2_sf(lb.q, lb.dof);
  return lb;
}

}  // namespace

std::vector<double> acf(std::span<const double> x, int max_lag) { return acf_of(x, max_lag); }

std::vector<double> pacf(std::span<const double> x, int max_lag) { return pacf_of_acf(acf_of(x, max_lag)); }

LjungBox ljung_box(std::span<const double> e, int lags, int fitted_params) {
  return ljung_box_of_acf(acf_of(e, lags), e.size(), fitted_params);
}

Whiteness whiteness(std::span<const double> e, int max_lag, int fitted_params) {
  Whiteness w;
  // One ACF for the three (pacf and ljung_box would each compute it again).
  w.acf = acf_of(e, max_lag);
  w.pacf = pacf_of_acf(w.acf);
  w.band = white_band(e.size());
  for (double v : w.acf) w.acf_outside += std::abs(v) > w.band;
  for (double v : w.pacf) w.pacf_outside += std::abs(v) > w.band;
  w.lb = ljung_box_of_acf(w.acf, e.size(), fitted_params);
  return w;
}

// Q(a,x) by the series for P when x < a+1 and Lentz's continued fraction otherwise
// (Numerical Recipes 6.2); both converge to double precision within a few hundred terms.
double gamma_q(double a, double x) {
  if (x <= 0.0) return 1.0;
  if (a <= 0.0) return 0.0;
  // lgamma_r, not std::lgamma: the latter writes glibc's global signgam, a data race when
  // fits run on several threads.
  int sign = 0;
  const double gln = ::lgamma_r(a, &sign);
  constexpr double eps = 1e-15;
  if (x < a + 1.0) {
    double ap = a, sum = 1.0 / a, del = sum;
    for (int n = 0; n < 10000; ++n) {
      ap += 1.0;
      del *= x / ap;
      sum += del;
      if (std::abs(del) < std::abs(sum) * eps) break;
    }
    const double p = sum * std::exp(-x + a * std::log(x) - gln);
    return std::clamp(1.0 - p, 0.0, 1.0);
  }
  constexpr double tiny = 1e-300;
  double b = x + 1.0 - a, c = 1.0 / tiny, d = 1.0 / b, h = d;
  for (int i = 1; i < 10000; ++i) {
    const double an = -i * (i - a);
    b += 2.0;
    d = an * d + b;
    if (std::abs(d) < tiny) d = tiny;
    c = b + an / c;
    if (std::abs(c) < tiny) c = tiny;
    d = 1.0 / d;
    const double del = d * c;
    h *= del;
    if (std::abs(del - 1.0) < eps) break;
  }
  return std::clamp(std::exp(-x + a * std::log(x) - gln) * h, 0.0, 1.0);
}

double chi2_sf(double x, double dof) { return gamma_q(0.5 * dof, 0.5 * x); }

std::vector<double> moving_average(std::span<const double> x, std::span<const double> w, int width) {
  assert(w.size() == x.size());
  const std::size_t n = x.size();
  std::vector<double> sx(n + 1, 0.0), sw(n + 1, 0.0), out(n);
  for (std::size_t t = 0; t < n; ++t) {
    sx[t + 1] = sx[t] + w[t] * x[t];
    sw[t + 1] = sw[t] + w[t];
  }
  const auto h = static_cast<std::size_t>(std::max(0, width / 2));
  for (std::size_t t = 0; t < n; ++t) {
    const std::size_t lo = t >= h ? t - h : 0, hi = std::min(n, t + h + 1);
    const double ww = sw[hi] - sw[lo];
    out[t] = ww > 0.0 ? (sx[hi] - sx[lo]) / ww : x[t];
  }
  return out;
}

}  // namespace fogbench::model

namespace fogbench::model {
double ar_process_std(std::span<const double> k, double sigma_a) {
  // psi_0 = 1, psi_j = sum_i k_i psi_{j-i}: the process is sum_j psi_j a_{t-j}.
  const std::size_t p = k.size();
  std::vector<double> psi{1.0};
  double s = 1.0;
  for (std::size_t j = 1; j < 100000; ++j) {
    double v = 0.0;
    for (std::size_t i = 1; i <= p && i <= j; ++i) v += k[i - 1] * psi[j - i];
    psi.push_back(v);
    s += v * v;
    if (!std::isfinite(s) || s > 1e12) return std::numeric_limits<double>::infinity();
    // Stop when the last p weights are negligible (the tail of a stable filter decays geometrically).
    bool small = j >= p;
    for (std::size_t i = 0; i < p && small; ++i) small = std::abs(psi[j - i]) < 1e-12;
    if (small) break;
  }
  return sigma_a * std::sqrt(s);
}
}  // namespace fogbench::model

namespace fogbench::model {
std::vector<double> ccf(std::span<const double> a, std::span<const double> x, int max_lag) {
  const std::size_t n = std::min(a.size(), x.size());
  const int L = std::max(0, max_lag);
  std::vector<double> r(2 * static_cast<std::size_t>(L) + 1, 0.0);
  double ma = 0.0, mx = 0.0;
  std::size_t na = 0, nx = 0;
  for (std::size_t t = 0; t < n; ++t) {
    if (std::isfinite(a[t])) ma += a[t], ++na;
    if (std::isfinite(x[t])) mx += x[t], ++nx;
  }
  if (na < 2 || nx < 2) return r;
  ma /= static_cast<double>(na);
  mx /= static_cast<double>(nx);
  double saa = 0.0, sxx = 0.0;
  for (std::size_t t = 0; t < n; ++t) {
    if (std::isfinite(a[t])) saa += (a[t] - ma) * (a[t] - ma);
    if (std::isfinite(x[t])) sxx += (x[t] - mx) * (x[t] - mx);
  }
  // N s_a s_x with population stds: sqrt(saa * sxx) when both have the same count, which
  // is the usual case (a residual and a regressor of one run); else scaled to a common N.
  const double denom = std::sqrt(saa / static_cast<double>(na) * sxx / static_cast<double>(nx)) * static_cast<double>(std::min(na, nx));
  if (!(denom > 0.0)) return r;
  for (int k = -L; k <= L; ++k) {
    double c = 0.0;
    for (std::size_t t = 0; t < n; ++t) {
      const long j = static_cast<long>(t) - k;
      if (j < 0 || j >= static_cast<long>(n)) continue;
      const double av = a[t], xv = x[static_cast<std::size_t>(j)];
      if (std::isfinite(av) && std::isfinite(xv)) c += (av - ma) * (xv - mx);
    }
    r[static_cast<std::size_t>(k + L)] = c / denom;
  }
  return r;
}

double normal_quantile(double p) {
  if (!(p > 0.0 && p < 1.0)) return std::numeric_limits<double>::quiet_NaN();
  // Bisection on Phi(z) = erfc(-z / sqrt 2) / 2, monotone; 80 halvings of [-40, 40] reach
  // 80 / 2^80, far below the 1e-9 promised.
  double lo = -40.0, hi = 40.0;
  for (int i = 0; i < 80; ++i) {
    const double mid = 0.5 * (lo + hi);
    if (0.5 * std::erfc(-mid / std::sqrt(2.0)) < p) lo = mid;
    else hi = mid;
  }
  return 0.5 * (lo + hi);
}

double confidence_band(std::size_t n, double level) {
  if (n == 0 || !(level > 0.0 && level < 1.0)) return std::numeric_limits<double>::quiet_NaN();
  return normal_quantile(0.5 * (1.0 + level)) / std::sqrt(static_cast<double>(n));
}
}  // namespace fogbench::model
