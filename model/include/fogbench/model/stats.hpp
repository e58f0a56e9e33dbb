// Time-series statistics of the paper's step 1: the 3-sigma outlier rule, the stationarity
// check, AR(p) by least squares, and the whiteness checks (ACF, PACF, Ljung-Box).
// Pure functions over spans of samples; a failure that can happen is a value.
#pragma once

#include <cmath>
#include <cstddef>
#include <expected>
#include <span>
#include <string>
#include <vector>

namespace fogbench::model {

double mean(std::span<const double> x);
// Sample standard deviation with the n-1 divisor (the paper's eq. 3). 0 for n < 2.
double stddev(std::span<const double> x);

// Pauta (3-sigma) rule, one pass as in the paper: keep[i] is false where |x_i - mean| > k*sigma.
struct OutlierResult {
  std::vector<bool> keep;
  std::size_t removed = 0;
  double mean = 0.0;   // mean of all samples, before removal
  double sigma = 0.0;  // sample std (n-1) of all samples, before removal
};
OutlierResult outliers_3sigma(std::span<const double> x, double k_sigma = 3.0);

// The paper's stationarity check: split the series in time order into m equal sub-series,
// gamma_i = mean_i + var_i; count m1 (gamma_i > mean gamma) and m2 (<=). The paper says
// stationary when m1 and m2 are "about equal" and gives no number. For white noise m1 is
// binomial(m, 1/2), so a tight rule raises false alarms (|m1 - m2| > 2 happens 34% of the
// time for m = 10); we call it non-stationary only when |m1 - m2| > 0.6 m, i.e. 9 of 10
// sub-series on one side (white noise does that 2% of the time). The check is informative
// and weak: a steady trend passes it, which is why the fit also reports Ljung-Box.
struct StationarityResult {
  int m = 0, m1 = 0, m2 = 0;
  bool stationary = false;
  std::vector<double> gamma;
};
StationarityResult stationarity_check(std::span<const double> y, int m = 10);

// AR(p) by least squares on a zero-mean series Y (paper eq. 8 and 13):
//   Y(t) = k1 Y(t-1) + ... + kp Y(t-p) + a_t,  t = p+1..N,
//   theta = (X'X)^-1 X'Y,  sigma_a^2 = (Y'Y - Y'X theta) / N   (N = the series length, as printed).
struct ArFit {
  std::vector<double> k;          // k1..kp
  double sigma_a2 = 0.0;          // innovation variance, (units of Y)^2
  std::vector<double> residuals;  // a_t for t = p+1..N (length N-p)
};
std::expected<ArFit, std::string> fit_ar(std::span<const double> y_zero_mean, int p = 2);

// Applies the AR filter (1 - k1 q^-1 - ... - kp q^-p) to x; samples before the start are
// taken equal to x[0] (the run starts from a steady hold).
std::vector<double> ar_filter(std::span<const double> x, std::span<const double> k);
// The same into out (resized; its capacity reused: no allocation once it has the size); out
// must not be x.
void ar_filter(std::span<const double> x, std::span<const double> k, std::vector<double>& out);

// Sample autocorrelation r_1..r_max_lag (r_0 = 1 omitted) of a series about its mean.
std::vector<double> acf(std::span<const double> x, int max_lag);
// Partial autocorrelation phi_11..phi_hh by Durbin-Levinson on the ACF.
std::vector<double> pacf(std::span<const double> x, int max_lag);
// The +-2/sqrt(N) band inside which a white series' ACF and PACF lie (95%).
inline double white_band(std::size_t n) { return n ? 2.0 / std::sqrt(static_cast<double>(n)) : 0.0; }

// Sample cross-correlation of a and x, as MATLAB's `resid` and `crosscorr` estimate it:
// r[k + max_lag] = sum_t (a_t - mean a)(x_{t-k} - mean x) / (N s_a s_x) for k = -max_lag..max_lag
// (x leads a by k samples when k > 0; s the population std, divisor N). a and x must have the
// same length N; pairs with a non-finite sample are left out of the sums (means and stds are
// over the finite samples). Length 2 max_lag + 1; zeros when either series is constant.
std::vector<double> ccf(std::span<const double> a, std::span<const double> x, int max_lag);
// The standard normal quantile z with P(Z <= z) = p, 0 < p < 1 (|error| < 1e-9).
double normal_quantile(double p);
// The two-sided band +-z/sqrt(N) inside which the sample ACF of a white series, or its sample
// CCF with any series independent of it, lies at each lag with probability `level`:
// z = normal_quantile((1 + level) / 2) (2.576 at 99%, MATLAB resid's default; 1.960 at 95%).
double confidence_band(std::size_t n, double level);

// Ljung-Box: Q = N (N+2) sum_{k=1..h} r_k^2 / (N-k), chi-square with h - fitted_params dof.
struct LjungBox {
  int lags = 0, dof = 0;
  double q = 0.0, p_value = 1.0;
};
LjungBox ljung_box(std::span<const double> residuals, int lags = 20, int fitted_params = 0);

// Whiteness of a residual series in one value: ACF, PACF, band, Ljung-Box.
struct Whiteness {
  std::vector<double> acf, pacf;
  double band = 0.0;
  int acf_outside = 0, pacf_outside = 0;  // lags >= 1 outside the band
  LjungBox lb;
  bool white(double alpha = 0.01) const { return lb.p_value >= alpha; }
};
Whiteness whiteness(std::span<const double> residuals, int max_lag = 20, int fitted_params = 0);

// The std of an AR(p) process y(t) = k1 y(t-1) + ... + kp y(t-p) + a_t with innovation std
// sigma_a: sigma_a * sqrt(sum_j psi_j^2), psi the impulse response of 1/(1 - k1 q^-1 - ...)
// (summed until it dies out). This is the std a model's compensated output should have when
// nothing but its own noise is left. Infinity when the filter is not stable.
double ar_process_std(std::span<const double> k, double sigma_a);

// Upper tail of the chi-square distribution, P(X > x) with dof degrees of freedom.
double chi2_sf(double x, double dof);
// Regularised upper incomplete gamma function Q(a, x).
double gamma_q(double a, double x);

// Centred moving average over `width` samples (width/2 each side, the window shrunk at the
// ends), each sample weighted by w (0: not counted); where a window holds no weight, x itself.
// Same units as x.
std::vector<double> moving_average(std::span<const double> x, std::span<const double> w, int width);

}  // namespace fogbench::model
