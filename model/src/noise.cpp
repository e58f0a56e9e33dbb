// The gyro's noise floor read off the settled holds of a model's residual; see noise.hpp.
//
// Why this file is longer than 800 lines: its one job is the floor, and the creep guard
// (creep_fast_acov .. remove_creep, about 330 lines: the regression of the holds on the
// thermistors, its score covariance under the floor's own noise and the Wald test) is the
// largest part of reading it. That guard is the seam to cut first: a noise_creep.cpp behind an
// internal header holding Stretch, CreepFit and floor_psd.
#include "fogbench/model/noise.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cassert>
#include <cmath>
#include <complex>
#include <cstdio>
#include <limits>
#include <numbers>
#include <optional>

#include "fogbench/model/model.hpp"
#include "fogbench/model/stats.hpp"

#include "allan_cov.hpp"

namespace fogbench::model {
namespace {

constexpr double kPi = std::numbers::pi;

// One-sided PSD of the AR(p) noise at 1 s samples, (deg/h)^2/Hz.
double ar_psd(std::span<const double> ar, double sigma_a, double f_hz) {
  std::complex<double> den{1.0, 0.0};
  for (std::size_t j = 0; j < ar.size(); ++j)
    den -= ar[j] * std::polar(1.0, -2.0 * kPi * f_hz * static_cast<double>(j + 1));
  return 2.0 * sigma_a * sigma_a / std::norm(den);
}

// |H|^2 of a centred moving average of w samples at f (Hz, 1 s samples).
double ma_gain2(int w, double f_hz) {
  if (w <= 1) return 1.0;
  const double s = std::sin(kPi * f_hz);
  if (std::abs(s) < 1e-300) return 1.0;
  const double r = std::sin(kPi * f_hz * w) / (w * s);
  return r * r;
}

// Overlapping Allan variance of the AR noise at cluster size m (samples):
// int_0^0.5 S(f) 2 sin^4(pi f m) / (m sin(pi f))^2 df, a midpoint sum fine enough to resolve
// the kernel's lobes (period 1/m in f).
double ar_avar(std::span<const double> ar, double sigma_a, std::int64_t m) {
  const auto md = static_cast<double>(m);
  const std::size_t steps = static_cast<std::size_t>(std::max<double>(4000.0, 40.0 * md));
  const double df = 0.5 / static_cast<double>(steps);
  double s = 0.0;
  for (std::size_t i = 0; i < steps; ++i) {
    const double f = (static_cast<double>(i) + 0.5) * df;
    const double sm = std::sin(kPi * f * md), s1 = std::sin(kPi * f);
    s += ar_psd(ar, sigma_a, f) * 2.0 * sm * sm * sm * sm / (md * md * s1 * s1);
  }
  return s * df;
}

// The q-quantile of a gamma law of shape a and scale 1 (bisection on gamma_q).
double gamma_quantile(double a, double q) {
  double lo = 0.0, hi = std::max(1.0, a);
  while (gamma_q(a, hi) > 1.0 - q) hi *= 2.0;
  for (int i = 0; i < 80; ++i) {
    const double mid = 0.5 * (lo + hi);
    (gamma_q(a, mid) > 1.0 - q ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

std::string fmt(double x, int d) {
  char b[48];
  std::snprintf(b, sizeof b, "%.*f", d, x);
  return b;
}

}  // namespace

double floor_avar(const NoiseFloor& f, double tau_s) {
  const auto m = std::max<std::int64_t>(1, std::llround(tau_s));
  const double fast = f.white_var_dph2 > 0.0 ? f.white_var_dph2 / static_cast<double>(m)
                                            : ar_avar(f.ar, f.sigma_a_dph, m);
  return fast + 2.0 * std::numbers::ln2 * f.flicker_h +
         2.0 * kPi * kPi / 3.0 * f.walk_h * tau_s;
}

namespace {

// The settled hold stretches of one run's residual, each a copy with short gaps bridged.
// A settled stretch, and whether it lies before the run's first ramp (the opening hold).
struct Stretch {
  std::vector<double> x;
  std::vector<double> t1_c, t2_c;  // the thermistors over the stretch, degC (empty: not recorded,
                                   // or not asked for: only remove_creep reads them)
  bool opening = false;
};
void settled_stretches(const FloorRun& fr, const NoiseFloorOptions& o, std::vector<Stretch>& out) {
  const RunData& run = *fr.run;
  const std::span<const double> residual_dph = fr.residual_dph, weight = fr.weight;
  const std::size_t n = std::min({run.size(), residual_dph.size(), weight.size()});
  const std::vector<Phase> ph = derive_phases(run);
  // Hold, evenly spaced at 1 s, past the settling time. A spike or a flagged sample (weight 0)
  // is bridged by the line between its neighbours when the gap is at most max_gap samples (a
  // spike must not cut a hold into pieces too short for its slow noise); a longer gap ends
  // the stretch.
  constexpr std::size_t max_gap = 10;
  double last_ramp_s = -std::numeric_limits<double>::infinity();
  std::vector<double> x(residual_dph.begin(), residual_dph.begin() + static_cast<std::ptrdiff_t>(n));
  auto good = [&](std::size_t k) { return weight[k] != 0.0 && std::isfinite(residual_dph[k]); };
  auto even = [&](std::size_t k) { return std::abs(run.time_s[k] - run.time_s[k - 1] - 1.0) < 0.01; };
  std::size_t i = 0;
  while (i < n) {
    if (ph[i] == Phase::heating || ph[i] == Phase::cooling) last_ramp_s = run.time_s[i];
    if (ph[i] != Phase::hold || !good(i)) {
      ++i;
      continue;
    }
    std::size_t j = i + 1, last_good = i;
    while (j < n && ph[j] == Phase::hold && even(j)) {
      if (good(j)) {
        for (std::size_t k = last_good + 1; k < j; ++k) {  // bridge the gap
          const double u = static_cast<double>(k - last_good) / static_cast<double>(j - last_good);
          x[k] = (1.0 - u) * residual_dph[last_good] + u * residual_dph[j];
        }
        last_good = j;
      } else if (j - last_good > max_gap) {
        break;
      }
      ++j;
    }
    j = last_good + 1;
    std::size_t b = i;
    while (b < j && run.time_s[b] - last_ramp_s < o.settle_s) ++b;
    if (j > b && j - b >= o.min_stretch_s) {
      const auto pb = static_cast<std::ptrdiff_t>(b), pj = static_cast<std::ptrdiff_t>(j);
      Stretch st{std::vector<double>(x.begin() + pb, x.begin() + pj), {}, {}, last_ramp_s == -std::numeric_limits<double>::infinity()};
      if (o.remove_creep && run.t1_c.size() >= j) st.t1_c.assign(run.t1_c.begin() + pb, run.t1_c.begin() + pj);
      if (o.remove_creep && run.t2_c.size() >= j) st.t2_c.assign(run.t2_c.begin() + pb, run.t2_c.begin() + pj);
      out.push_back(std::move(st));
    }
    i = j;
  }
}

// The part of the holds' residual that the thermistors' creep explains, taken out before the
// Allan curve is read. The coil thermistors still creep slowly through a hold after a ramp, and
// a thermal term the model misses (or a wrong one it holds) then moves the residual with them:
// read as slow noise, it would widen the limits and excuse itself and whatever else is
// missing. Regressors pooled over all stretches, each demeaned within its stretch: T1 and T2
// levels (degC), their rates (degC/s, a slope over +-rate_half_s) and their levels times the
// stretch's mean level (degC^2, for a term not linear in temperature).
//
// Taken out only when significant, by a Wald test whose variance is the gyro's own noise's: the
// scores g = X'y (X the regressors scaled to unit norm) have, under no creep, the covariance
// M = X' Sigma X with Sigma the noise's autocovariance within each stretch (a sandwich with the
// noise's long-range dependence in its meat). Sigma is the floor read on the holds as they are
// (`null_floor`: white or the model's AR at short lags, flicker h/f and random walk h/f^2,
// stretches independent), so W = g' M^-1 g is a chi-square of rank(M) degrees of freedom under
// no creep, however slowly the noise wanders. A residual autocovariance estimated from the same
// stretches (Newey-West, or the scalar 1 + 2 sum rho it replaces) is biased low for flicker and
// walk, whose correlation outlasts a hold, and its test was too liberal. Returns W (0: no
// regressor moved), its 99.9 % quantile and the variance taken out, (deg/h)^2.
struct CreepFit {
  double chi2_eff = 0.0, quantile = 0.0, removed_var_dph2 = 0.0;
  std::size_t dof = 0;
  bool removed = false;
};

// The short-term part's autocovariance at lags 0.. (the white level read off the holds, or the
// model's AR(p) with its sigma_a), (deg/h)^2; cut where it falls under 1e-6 of lag 0.
std::vector<double> creep_fast_acov(const NoiseFloor& f) {
  if (f.white_var_dph2 > 0.0 || f.ar.empty()) return {f.white_var_dph2 > 0.0 ? f.white_var_dph2 : f.sigma_a_dph * f.sigma_a_dph};
  std::vector<double> psi{1.0};  // the AR filter's impulse response
  const std::size_t p = f.ar.size();
  for (std::size_t j = 1; j < 20000; ++j) {
    double v = 0.0;
    for (std::size_t i = 1; i <= p && i <= j; ++i) v += f.ar[i - 1] * psi[j - i];
    if (!std::isfinite(v) || std::abs(v) > 1e6) return {f.sigma_a_dph * f.sigma_a_dph};  // not stationary: white at sigma_a
    psi.push_back(v);
    bool small = j >= p;
    for (std::size_t i = 0; i < p && small; ++i) small = std::abs(psi[j - i]) < 1e-9;
    if (small) break;
  }
  std::vector<double> g;
  const double s2 = f.sigma_a_dph * f.sigma_a_dph;
  for (std::size_t l = 0; l < psi.size() && l <= 600; ++l) {
    double v = 0.0;
    for (std::size_t j = 0; j + l < psi.size(); ++j) v += psi[j] * psi[j + l];
    g.push_back(s2 * v);
    if (l > 0 && std::abs(g.back()) < 1e-6 * g.front()) break;
  }
  return g;
}

// Step 1, the regression: the creep regressors pooled over every stretch, each demeaned within
// its stretch and scaled to unit norm (levels and rates differ by orders of magnitude; columns
// that never move are left out), the hold residual demeaned the same way, and its least-squares
// fit on them. Empty when no regressor moves or the holds are too short for them.
struct CreepRegression {
  Eigen::MatrixXd X;       // n x p, unit-norm columns
  Eigen::VectorXd y, fit;  // the demeaned hold residual and its fit on X, deg/h
  Eigen::Index rank = 0;   // the fit's rank
};

std::optional<CreepRegression> creep_regression(const std::vector<Stretch>& spans) {
  constexpr std::size_t rate_half_s = 30;
  std::size_t n = 0;
  for (const auto& sp : spans) n += sp.x.size();
  // A stretch without a thermistor contributes zeros to its columns.
  auto demeaned = [](const std::vector<double>& v, std::vector<double>& col) {
    double m = 0.0;
    for (double x : v) m += x;
    m /= static_cast<double>(v.size());
    for (double x : v) col.push_back(x - m);
  };
  auto level = [&](const std::vector<double>& t, std::size_t len, std::vector<double>& col) {
    if (t.size() == len)
      demeaned(t, col);
    else
      col.insert(col.end(), len, 0.0);
  };
  auto rate = [&](const std::vector<double>& t, std::size_t len, std::vector<double>& col) {
    if (t.size() != len || len < 2) {
      col.insert(col.end(), len, 0.0);
      return;
    }
    std::vector<double> r(len);  // degC/s at 1 s samples
    for (std::size_t i = 0; i < len; ++i) {
      const std::size_t a = i > rate_half_s ? i - rate_half_s : 0, b = std::min(len - 1, i + rate_half_s);
      r[i] = (t[b] - t[a]) / static_cast<double>(b - a);
    }
    demeaned(r, col);
  };
  // A level times its stretch's mean level (degC^2): a term the model misses that is not linear
  // in temperature (T1^2, a product) moves the residual in a hold by its slope at the hold's
  // temperature, 2 T dT for T^2, which one pooled coefficient per level cannot follow across
  // holds at different temperatures (its misfit in the other holds would read as slow noise).
  auto level_at = [&](const std::vector<double>& t, std::size_t len, std::vector<double>& col) {
    if (t.size() != len) {
      col.insert(col.end(), len, 0.0);
      return;
    }
    double m = 0.0;
    for (double x : t) m += x;
    m /= static_cast<double>(len);
    for (double x : t) col.push_back((x - m) * m);
  };
  std::vector<std::vector<double>> cols(6);
  std::vector<double> y;
  y.reserve(n);
  for (const auto& sp : spans) {
    const std::size_t len = sp.x.size();
    level(sp.t1_c, len, cols[0]);
    level(sp.t2_c, len, cols[1]);
    rate(sp.t1_c, len, cols[2]);
    rate(sp.t2_c, len, cols[3]);
    level_at(sp.t1_c, len, cols[4]);
    level_at(sp.t2_c, len, cols[5]);
    demeaned(sp.x, y);
  }
  std::vector<std::size_t> use;
  std::vector<double> scale;
  for (std::size_t c = 0; c < cols.size(); ++c) {
    double ss = 0.0;
    for (double v : cols[c]) ss += v * v;
    if (std::sqrt(ss) > 1e-9) {
      use.push_back(c);
      scale.push_back(1.0 / std::sqrt(ss));
    }
  }
  if (use.empty() || n < 10 * use.size() + spans.size()) return std::nullopt;
  const auto ni = static_cast<Eigen::Index>(n);
  CreepRegression r;
  r.X.resize(ni, static_cast<Eigen::Index>(use.size()));
  for (std::size_t c = 0; c < use.size(); ++c)
    for (std::size_t i = 0; i < n; ++i) r.X(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(c)) = cols[use[c]][i] * scale[c];
  r.y = Eigen::Map<const Eigen::VectorXd>(y.data(), ni);
  // A column with under 1 % of its norm its own (the rest follows the others) is left out of
  // the fit: nearly collinear levels would take huge opposite coefficients and put the
  // thermistors' own noise, amplified, into the residual.
  Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(r.X);
  qr.setThreshold(1e-2);
  r.rank = qr.rank();
  if (r.rank == 0) return std::nullopt;
  r.fit = r.X * qr.solve(r.y);
  return r;
}

// One stretch's regressors as Q Rt: Q (len x r) orthonormal, Rt (r x p), r the rank within the
// stretch (a level times the stretch's mean level is that level scaled, so r <= 4 of 6). The
// variances below are computed on Q's r columns and carried back by Rt' (.) Rt; what a rank
// cut drops is under 1e-12 of the columns' norm.
struct StretchBasis {
  Eigen::MatrixXd q, rt;
};
StretchBasis stretch_basis(const Eigen::Ref<const Eigen::MatrixXd>& xs) {
  Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(xs);
  qr.setThreshold(1e-12);
  const Eigen::Index r = qr.rank(), p = xs.cols();
  StretchBasis b;
  b.q = qr.householderQ() * Eigen::MatrixXd::Identity(xs.rows(), r);
  const Eigen::MatrixXd R = qr.matrixR().topLeftCorner(r, p).triangularView<Eigen::Upper>();
  b.rt = R * qr.colsPermutation().transpose();
  return b;
}

// int S_slow(f) Re(C_a(f) C_b(f)*) df over the columns of q (one stretch, 1 s samples), C the
// columns' transforms, S_slow = h1 / f + h2 / f^2: the trapezoid in ln f over `grid` points
// from e^ln_lo to e^(ln_lo + (grid - 1) step) Hz (df = f dln f). Only Re(C C^H) is needed, so
// each transform may carry a phase common to the columns. Where w = 2 pi f is small against
// the stretch (w half-length <= 1) the transform is a power series in w of the columns' moments
// about the stretch's middle (20 terms: under 1e-18 of the columns' sums), computed once for
// all those frequencies; above, a direct sum with a rotating phasor.
Eigen::MatrixXd slow_cross_spectrum(const Eigen::MatrixXd& q, double h1, double h2, double ln_lo, double step, int grid) {
  const Eigen::Index len = q.rows(), r = q.cols();
  Eigen::MatrixXd mq = Eigen::MatrixXd::Zero(r, r);
  if (len == 0 || r == 0 || grid < 1) return mq;
  const double half = 0.5 * static_cast<double>(len - 1);
  const double u_scale = half > 0.0 ? 1.0 / half : 0.0;
  constexpr int terms = 20;
  const auto ng = static_cast<Eigen::Index>(grid);
  Eigen::MatrixXcd cs(r, ng);  // each frequency's transforms
  std::vector<double> fks(static_cast<std::size_t>(grid));
  std::vector<Eigen::Index> direct;
  Eigen::MatrixXd mom;  // (terms + 1) x r: sum_n q(n, c) u_n^k, u_n = (n - half) / half in [-1, 1]
  const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> rows = q;
  for (Eigen::Index k = 0; k < ng; ++k) {
    const double fk = std::exp(ln_lo + step * static_cast<double>(k)), w = 2.0 * kPi * fk;
    fks[static_cast<std::size_t>(k)] = fk;
    if (w * half > 1.0) {
      direct.push_back(k);
      continue;
    }
    if (mom.size() == 0) {
      mom = Eigen::MatrixXd::Zero(terms + 1, r);
      for (Eigen::Index i = 0; i < len; ++i) {
        const double u = (static_cast<double>(i) - half) * u_scale;
        double pw = 1.0;
        for (int t = 0; t <= terms; ++t) {
          mom.row(t) += pw * rows.row(i);
          pw *= u;
        }
      }
    }
    // sum_n q_n e^{-i w (n - half)} = sum_t (-i w half)^t / t! mom_t
    const double a = w * half;
    std::complex<double> coef{1.0, 0.0};
    Eigen::VectorXcd c = Eigen::VectorXcd::Zero(r);
    for (int t = 0; t <= terms; ++t) {
      c += coef * mom.row(t).transpose().cast<std::complex<double>>();
      coef *= std::complex<double>(0.0, -a / static_cast<double>(t + 1));
    }
    cs.col(k) = c;
  }
  // The direct sums, four frequencies a pass: each phasor's rotation is a chain of dependent
  // multiplications, and four independent chains keep the processor busy where one waits on
  // its own latency.
  constexpr std::size_t block = 4, max_cols = 8;  // the creep regressors are 6
  assert(static_cast<std::size_t>(r) <= max_cols);
  for (std::size_t d0 = 0; d0 < direct.size(); d0 += block) {
    const std::size_t nb = std::min(block, direct.size() - d0);
    double zr[block], zi[block], cr[block], ci[block], are[block][max_cols], aim[block][max_cols];
    for (std::size_t b = 0; b < block; ++b) {
      const double w = b < nb ? 2.0 * kPi * fks[static_cast<std::size_t>(direct[d0 + b])] : 0.0;
      zr[b] = 1.0;
      zi[b] = 0.0;
      cr[b] = std::cos(w);
      ci[b] = -std::sin(w);
      for (std::size_t j = 0; j < max_cols; ++j) are[b][j] = aim[b][j] = 0.0;
    }
    const auto rc = static_cast<std::size_t>(r);
    for (Eigen::Index i = 0; i < len; ++i) {
      const double* x = rows.data() + i * r;
      for (std::size_t b = 0; b < block; ++b) {
        for (std::size_t j = 0; j < rc; ++j) {
          are[b][j] += x[j] * zr[b];
          aim[b][j] += x[j] * zi[b];
        }
        const double nr = zr[b] * cr[b] - zi[b] * ci[b];
        zi[b] = zr[b] * ci[b] + zi[b] * cr[b];
        zr[b] = nr;
      }
    }
    for (std::size_t b = 0; b < nb; ++b)
      for (std::size_t j = 0; j < rc; ++j) cs(static_cast<Eigen::Index>(j), direct[d0 + b]) = std::complex<double>(are[b][j], aim[b][j]);
  }
  for (Eigen::Index k = 0; k < ng; ++k) {
    // One-sided S(f) df with df = f dln f, trapezoid weights.
    const double fk = fks[static_cast<std::size_t>(k)];
    const double wt = (h1 / fk + h2 / (fk * fk)) * fk * step * (k == 0 || k == ng - 1 ? 0.5 : 1.0);
    mq += wt * (cs.col(k) * cs.col(k).adjoint()).real();
  }
  return mq;
}

// Step 2, the sandwich: the covariance of the scores g = X'y under no creep, M = X' Sigma X,
// Sigma the floor's noise within each stretch (stretches independent). The short-term part in
// time (its autocovariance is a few lags long), the slow part in frequency
// (int S_slow(f) Re(C_a(f) C_b(f)*) df, C_a the regressor's transform over the stretch; finite
// since each column sums to 0 in a stretch), on a log grid in f fine enough for the stretches'
// lengths.
Eigen::MatrixXd creep_score_covariance(const CreepRegression& reg, const std::vector<Stretch>& spans, const NoiseFloor& null_floor) {
  const Eigen::Index p = reg.X.cols();
  Eigen::MatrixXd M = Eigen::MatrixXd::Zero(p, p);
  std::vector<double> fast = creep_fast_acov(null_floor);
  // The regression's residual variance stands for the short-term level where the floor saw no
  // slow law (the model's AR noise was fitted on the opening hold alone and may be a different
  // level from the holds').
  if (!null_floor.slow()) {
    const double dof = static_cast<double>(reg.X.rows()) - static_cast<double>(spans.size()) - static_cast<double>(reg.rank);
    const double var_e = dof >= 1.0 ? (reg.y - reg.fit).squaredNorm() / dof : 0.0;
    if (var_e > 0.0 && fast.front() > 0.0) {
      const double k = var_e / fast.front();
      for (double& v : fast) v *= k;
    }
  }
  const double slow_h1 = null_floor.flicker_h, slow_h2 = null_floor.walk_h + null_floor.walk_bound_h;
  std::size_t longest = 0;
  for (const auto& sp : spans) longest = std::max(longest, sp.x.size());
  constexpr int grid = 200;
  const double f_lo = std::log(std::min(1e-6, 0.01 / static_cast<double>(longest))), f_hi = std::log(0.5);
  const double step = (f_hi - f_lo) / (grid - 1);
  Eigen::Index off = 0;
  for (const auto& sp : spans) {
    const auto len = static_cast<Eigen::Index>(sp.x.size());
    const StretchBasis b = stretch_basis(reg.X.middleRows(off, len));
    off += len;
    if (b.q.cols() == 0) continue;
    Eigen::MatrixXd mq = Eigen::MatrixXd::Zero(b.q.cols(), b.q.cols());
    // Exact over the first exact_lags lags; beyond, the regressors (levels, and rates over
    // +-30 s) barely change within a lag, so x_t x_{t+l}' is taken as x_t x_t' (a long AR tail
    // would otherwise cost a pass over the stretch per lag). Q'Q = I.
    constexpr std::size_t exact_lags = 30;
    double tail = 0.0;
    for (std::size_t l = 0; l < fast.size() && static_cast<Eigen::Index>(l) < len; ++l) {
      if (l > exact_lags) {
        tail += fast[l];
        continue;
      }
      const auto L = static_cast<Eigen::Index>(l);
      const Eigen::MatrixXd cross = b.q.topRows(len - L).transpose() * b.q.bottomRows(len - L);
      mq += fast[l] * (l == 0 ? cross : Eigen::MatrixXd(cross + cross.transpose()));
    }
    if (tail != 0.0) mq += 2.0 * tail * Eigen::MatrixXd::Identity(b.q.cols(), b.q.cols());
    if (slow_h1 > 0.0 || slow_h2 > 0.0) mq += slow_cross_spectrum(b.q, slow_h1, slow_h2, f_lo, step, grid);
    M += b.rt.transpose() * mq * b.rt;
  }
  return M;
}

// Step 3, the Wald test: W = g' M^+ g over M's directions that carry variance (near-collinear
// regressors leave directions with none: they are dropped, and with them their degrees of
// freedom), a chi-square of that many degrees of freedom under no creep; its (1 - p_false)
// quantile. Empty when M carries no variance.
struct WaldTest {
  double chi2 = 0.0, quantile = 0.0;
  std::size_t dof = 0;
};
std::optional<WaldTest> creep_wald(const Eigen::VectorXd& g, const Eigen::MatrixXd& M, double p_false) {
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(M);
  if (es.info() != Eigen::Success) return std::nullopt;
  const double lmax = es.eigenvalues().maxCoeff();
  if (!(lmax > 0.0)) return std::nullopt;
  WaldTest w;
  for (Eigen::Index k = 0; k < M.rows(); ++k) {
    const double lk = es.eigenvalues()(k);
    if (!(lk > 1e-8 * lmax)) continue;
    const double proj = es.eigenvectors().col(k).dot(g);
    w.chi2 += proj * proj / lk;
    ++w.dof;
  }
  if (w.dof == 0) return std::nullopt;
  // The chi-square of dof degrees of freedom is 2 x a gamma of shape dof / 2.
  w.quantile = 2.0 * gamma_quantile(0.5 * static_cast<double>(w.dof), 1.0 - p_false);
  return w;
}

CreepFit remove_creep(std::vector<Stretch>& spans, const NoiseFloor& null_floor) {
  constexpr double p_false = 1e-3;
  CreepFit cf;
  const std::optional<CreepRegression> reg = creep_regression(spans);
  if (!reg) return cf;
  const Eigen::MatrixXd M = creep_score_covariance(*reg, spans, null_floor);
  const Eigen::VectorXd g = reg->X.transpose() * reg->y;
  const std::optional<WaldTest> w = creep_wald(g, M, p_false);
  if (!w) return cf;
  cf.chi2_eff = w->chi2;
  cf.dof = w->dof;
  cf.quantile = w->quantile;
  if (!(cf.chi2_eff > cf.quantile)) return cf;
  cf.removed = true;
  cf.removed_var_dph2 = reg->fit.squaredNorm() / static_cast<double>(reg->fit.size());
  Eigen::Index off = 0;
  for (auto& sp : spans) {
    for (std::size_t i = 0; i < sp.x.size(); ++i) sp.x[i] -= reg->fit(off + static_cast<Eigen::Index>(i));
    off += static_cast<Eigen::Index>(sp.x.size());
  }
  return cf;
}

}  // namespace

double floor_psd(const NoiseFloor& f, double f_hz) {
  const double fk = std::max(f_hz, 1e-9);
  const double fast = f.white_var_dph2 > 0.0 ? 2.0 * f.white_var_dph2 : ar_psd(f.ar, f.sigma_a_dph, fk);
  return fast + f.flicker_h / fk + f.walk_h / (fk * fk);
}

double floor_slow_variance(const NoiseFloor& f, std::span<const double> c) {
  if (!f.slow() || c.empty()) return 0.0;
  // A log grid from 1e-7 Hz to 0.5 Hz, the integral in ln f (dF = f dln f).
  constexpr int points = 3000;
  const double lo = std::log(1e-7), hi = std::log(0.5), step = (hi - lo) / (points - 1);
  double sum = 0.0, prev = 0.0;
  for (int k = 0; k < points; ++k) {
    const double fk = std::exp(lo + step * k);
    std::complex<double> cf{0.0, 0.0};
    for (std::size_t i = 0; i < c.size(); ++i) cf += c[i] * std::polar(1.0, -2.0 * kPi * fk * static_cast<double>(i));
    const double g = (f.flicker_h / fk + f.walk_h / (fk * fk)) * std::norm(cf) * fk;
    if (k > 0) sum += 0.5 * (g + prev) * step;
    prev = g;
  }
  return sum;
}

NoiseFloor estimate_noise_floor(const RunData& run, std::span<const double> residual_dph, std::span<const double> weight,
                                std::span<const double> ar, double sigma_a_dph, const NoiseFloorOptions& o) {
  const FloorRun one{&run, residual_dph, weight};
  return estimate_noise_floor(std::span<const FloorRun>(&one, 1), ar, sigma_a_dph, o);
}

namespace {

// The floor's laws read off the stretches' pooled Allan curve (below), with the model's AR
// noise as the fallback; the note says how it was read.
// bound_always: the walk the holds cannot exclude read even where no flicker is seen (the creep
// guard's null noise, remove_creep; the floor itself bounds it only beside flicker).
NoiseFloor read_floor_laws(const std::vector<Stretch>& spans, std::span<const double> ar, double sigma_a_dph, const NoiseFloorOptions& o,
                           bool bound_always = false) {
  NoiseFloor fl;
  fl.ar.assign(ar.begin(), ar.end());
  fl.sigma_a_dph = sigma_a_dph;
  std::size_t total = 0;
  for (const auto& sp : spans) total += sp.x.size();
  // The pooled curve: each stretch's overlapping Allan variance at half-octave cluster sizes up
  // to a third of it, weighted by its number of terms; degrees of freedom N/m - 1 summed (IEEE
  // 952's conservative count).
  std::size_t longest = 0;
  for (const auto& sp : spans) longest = std::max(longest, sp.x.size());
  std::vector<std::int64_t> sizes;
  for (double md = 1.0; static_cast<std::size_t>(3.0 * std::round(md)) <= longest; md *= std::numbers::sqrt2) {
    const auto m = static_cast<std::int64_t>(std::llround(md));
    if (sizes.empty() || m != sizes.back()) sizes.push_back(m);
  }
  // Pooled in two groups, the opening holds (before any ramp) and the later holds; at each tau
  // their weighted mean, or the smaller group's where the two differ beyond their scatter: the gyro's slow noise shows in
  // both alike, while what a model misses shows in one only: a warm-up after power-on decays
  // through the opening holds, a thermal term's tail (a second path, a slow mount) runs through
  // the holds after ramps. Either would otherwise pass for slow noise and excuse itself.
  struct Acc {
    double avar = 0.0, terms = 0.0, dof = 0.0;
  };
  std::vector<Acc> open_acc(sizes.size()), late_acc(sizes.size());
  for (const auto& sp : spans) {
    const std::size_t len = sp.x.size();
    std::vector<std::int64_t> ms;
    for (auto m : sizes)
      if (static_cast<std::size_t>(3 * m) <= len) ms.push_back(m);
    auto c = allan::overlapping_adev(sp.x, 1.0, ms);
    if (!c) continue;
    auto& acc = sp.opening ? open_acc : late_acc;
    for (std::size_t k = 0; k < c->size(); ++k) {
      const double t = static_cast<double>((*c)[k].terms);
      acc[k].avar += t * (*c)[k].adev_dph * (*c)[k].adev_dph;
      acc[k].terms += t;
      acc[k].dof += std::max(1.0, static_cast<double>(len) / static_cast<double>(sizes[k]) - 1.0);
    }
  }
  std::vector<double> avar(sizes.size(), 0.0), terms(sizes.size(), 0.0), edf(sizes.size(), 0.0);
  // The groups each point was pooled over (1 the opening holds, 2 the later ones): the walk's
  // test below counts its estimates' covariance over those stretches.
  std::vector<unsigned> groups(sizes.size(), 3u);
  std::vector<std::size_t> pts;
  for (std::size_t k = 0; k < sizes.size(); ++k) {
    const Acc& a = open_acc[k];
    const Acc& b = late_acc[k];
    if (a.terms <= 0.0 && b.terms <= 0.0) continue;
    Acc use{a.avar + b.avar, a.terms + b.terms, a.dof + b.dof};
    if (a.terms > 0.0 && b.terms > 0.0 && a.avar > 0.0 && b.avar > 0.0) {
      // The groups differ beyond their scatter (log of a ratio of chi-square estimates: variance
      // 2/dof each; 2.58 sigma): the smaller stands for the gyro.
      const double lr = std::log((a.avar / a.terms) / (b.avar / b.terms));
      if (std::abs(lr) > 2.58 * std::sqrt(2.0 / a.dof + 2.0 / b.dof)) {
        use = lr < 0.0 ? a : b;
        groups[k] = lr < 0.0 ? 1u : 2u;
      }
    }
    avar[k] = use.avar / use.terms;
    terms[k] = use.terms;
    edf[k] = use.dof;
    if (avar[k] > 0.0) pts.push_back(k);
  }
  fl.hold_samples = total;
  fl.stretches = spans.size();
  if (pts.size() < 3) {
    fl.note = "settled holds too short for an Allan curve: the model's AR noise alone";
    return fl;
  }
  for (std::size_t k : pts) {
    allan::AdevPoint p;
    p.m = sizes[k];
    p.tau_s = static_cast<double>(sizes[k]);
    p.adev_dph = std::sqrt(avar[k]);
    const double rel = 1.0 / std::sqrt(2.0 * edf[k]);
    p.ci_low_dph = std::max(0.0, p.adev_dph * (1.0 - rel));
    p.ci_high_dph = p.adev_dph * (1.0 + rel);
    p.terms = static_cast<std::int64_t>(terms[k]);
    fl.curve.push_back(p);
    fl.longest_tau_s = p.tau_s;
  }
  // Fit AVAR(tau) = a AVAR_AR(tau) + c_f + c_w tau (a, c_f, c_w >= 0) by least squares on the
  // relative misfit, each point weighted by its degrees of freedom / 2 (var of a chi-square
  // estimate over its mean^2 is 2 / edf). The slow laws enter only when they earn their place.
  const std::size_t np = pts.size();
  // The short-term part as white noise (AVAR = c0 / tau): the paper's AR(2), fitted on the
  // opening hold alone, absorbs some of a FOG's flicker into its coefficients, and its Allan
  // shape is then no law of the gyro's (a bump at 3 to 30 s); a FOG's own short-term noise is
  // angle random walk, white in rate.
  std::vector<double> base(np);
  for (std::size_t q = 0; q < np; ++q) base[q] = 1.0 / static_cast<double>(sizes[pts[q]]);
  struct Sol {
    double a = 0, cf = 0, cw = 0, chi2 = std::numeric_limits<double>::infinity();
    bool ok = false;
  };
  // Weighted by the model's own variance at each point (iterated from the observed curve):
  // weights from the observed values would favour the points that came out low, and a random
  // walk read off a few long clusters would be biased low.
  // fixed_cw >= 0: the walk's part held at that value, (deg/h)^2/s (the bound's profile below).
  // Non-negative least squares (the laws' variances cannot be negative): every subset of the
  // laws asked for is solved, the best whose coefficients are all >= 0 kept. Rejecting a set
  // whose unconstrained solution had one negative coefficient (a flat curve over a white level
  // too small to read gives a slightly negative one beside flicker) left only sets that fit
  // the curve worse, and a walk ran away among them.
  // from: the points of the curve fitted start there (0: all; the walk's tests below read the
  // long taus alone).
  auto solve_once = [&](bool use_f, bool use_w, const std::vector<double>& ref, double fixed_cw, std::size_t from) {
    Sol s;
    Eigen::MatrixXd X(static_cast<Eigen::Index>(np), 3);
    Eigen::VectorXd y(static_cast<Eigen::Index>(np));
    for (std::size_t q = 0; q < np; ++q) {
      const std::size_t p = pts[q];
      // Half-octave points overlap their neighbours' clusters: each counts half its dof.
      const double w = q < from ? 0.0 : std::sqrt(edf[p] / 4.0) / ref[q];
      const auto r = static_cast<Eigen::Index>(q);
      X(r, 0) = w * base[q];
      X(r, 1) = w;
      X(r, 2) = w * static_cast<double>(sizes[p]);
      y(r) = w * (avar[p] - std::max(0.0, fixed_cw) * static_cast<double>(sizes[p]));
    }
    const unsigned asked = 1u | (use_f ? 2u : 0u) | (use_w ? 4u : 0u);
    for (unsigned set = 1; set < 8; ++set) {
      if ((set & ~asked) != 0) continue;
      std::vector<Eigen::Index> cols;
      for (Eigen::Index c = 0; c < 3; ++c)
        if (set & (1u << c)) cols.push_back(c);
      Eigen::MatrixXd Xs(X.rows(), static_cast<Eigen::Index>(cols.size()));
      for (std::size_t c = 0; c < cols.size(); ++c) Xs.col(static_cast<Eigen::Index>(c)) = X.col(cols[c]);
      const Eigen::VectorXd b = Xs.colPivHouseholderQr().solve(y);
      bool nonneg = true;
      for (Eigen::Index c = 0; c < b.size(); ++c) nonneg = nonneg && b(c) >= 0.0;
      if (!nonneg) continue;
      const double chi2 = (Xs * b - y).squaredNorm();
      if (!(chi2 < s.chi2)) continue;
      Sol t;
      double coef[3] = {0.0, 0.0, 0.0};
      for (std::size_t c = 0; c < cols.size(); ++c) coef[cols[c]] = b(static_cast<Eigen::Index>(c));
      t.a = coef[0];
      t.cf = coef[1];
      t.cw = fixed_cw >= 0.0 ? fixed_cw : coef[2];
      t.chi2 = chi2;
      t.ok = true;
      s = t;
    }
    return s;
  };
  auto solve = [&](bool use_f, bool use_w, double fixed_cw = -1.0, std::size_t from = 0) {
    std::vector<double> ref(np);
    for (std::size_t q = 0; q < np; ++q) ref[q] = avar[pts[q]];
    Sol s = solve_once(use_f, use_w, ref, fixed_cw, from);
    for (int it = 0; it < 4 && s.ok; ++it) {
      for (std::size_t q = 0; q < np; ++q)
        ref[q] = std::max(1e-300, s.a * base[q] + s.cf + s.cw * static_cast<double>(sizes[pts[q]]));
      Sol next = solve_once(use_f, use_w, ref, fixed_cw, from);
      if (!next.ok) break;
      s = next;
    }
    return s;
  };
  // The deviance of the curve's estimates under a law, each a chi-square of edf degrees of
  // freedom about the law's value m (half its edf: half-octave points overlap):
  // sum edf/2 (y/m - 1 - ln(y/m)); near the law (y/m near 1) it is the weighted misfit the laws
  // are fitted by, edf/4 (y/m - 1)^2. That misfit saturates as m grows (a relative misfit tends
  // to 1), so it cannot exclude a law that overshoots: a walk read off a flat curve, its long
  // taus far above their estimates and weighted down by its own values (1.1 deg/h/sqrt(h) on a
  // flat curve of 0.033 deg/h). The laws are chosen by the deviance, which can.
  auto point_deviance = [&](const Sol& s, std::size_t q) {
    const std::size_t p = pts[q];
    const double m = s.a * base[q] + s.cf + s.cw * static_cast<double>(sizes[p]);
    if (!(m > 0.0)) return std::numeric_limits<double>::infinity();
    const double r = avar[p] / m;
    return 0.5 * edf[p] * (r - 1.0 - std::log(r));
  };
  auto deviance = [&](const Sol& s, std::size_t from = 0) {
    double d = 0.0;
    for (std::size_t q = from; q < np; ++q) d += point_deviance(s, q);
    return d;
  };
  // A walk is identifiable at the long taus only: at the short ones it can only bend the
  // short-term part's shape, which a real FOG's noise (and the simulator's flicker, a sum of
  // Markov processes whose curve still rises from 1 to ~10 s) does not follow exactly, and a
  // white level too small to read leaves that rise to the walk (a walk of 1.1 deg/h/sqrt(h)
  // read off a flat curve of 0.033 deg/h at white 0.006 deg/h). The walk's bound (below) is
  // read on the curve's last six octaves alone (tau >= the longest / 64), the other laws
  // refitted there: how much the law with a walk of cw lowers their deviance against the same
  // laws without it (negative: it fits them worse).
  std::size_t long_from = 0;
  while (long_from + 1 < np && 64 * sizes[pts[long_from]] < sizes[pts.back()]) ++long_from;
  auto long_walk_gain = [&](double cw) {
    const Sol without = solve(true, false, -1.0, long_from);
    const Sol with = solve(true, false, cw, long_from);
    if (!without.ok) return 0.0;
    if (!with.ok) return -std::numeric_limits<double>::infinity();
    return deviance(without, long_from) - deviance(with, long_from);
  };
  // The degrees of freedom the walk's test may count on the long taus. The deviance takes each
  // point as an independent chi-square of half its edf; but the points' clusters overlap within
  // a point and across half-octave neighbours, and under flicker (long-range correlated) the
  // estimates move together more than under white noise: a walk read off a flat flicker curve
  // gained 4.2 to 16.4 in 4 of 40 synthetic 30 min holds, the gains' upper tail about 2.4 x
  // that of the half chi-square of one degree of freedom the test assumes. The likelihood-ratio
  // gain is, near the null law, the square of the walk's efficient score over its variance as
  // the deviance counts it; under flicker its variance under the estimates' real covariance
  // (allan_cov: the overlapping estimates' covariance under the null law, pooled over the
  // stretches each point was read on) is larger. The gain is scaled by the ratio of the two (a
  // sandwich correction: 1 when the deviance's count is right), which follows the noise: about
  // 0.6 under flicker in 30 min holds, 1 to 1.6 where white noise dominates the long taus (the
  // deviance's half count is cautious there). docs/workbench.md "Walks read off flat curves".
  auto walk_dof_scale = [&](const Sol& null, std::size_t from) {
    const std::size_t k = np - from;
    if (k < 2 || !null.ok) return 1.0;
    std::vector<std::int64_t> ms(k);
    for (std::size_t i = 0; i < k; ++i) ms[i] = sizes[pts[from + i]];
    const detail::AvarLaws law{null.a, null.cf, 0.0};
    Eigen::MatrixXd cov = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(k), static_cast<Eigen::Index>(k));
    std::vector<double> pooled_terms(k, 0.0), n_at(k);
    for (const auto& sp : spans) {
      const unsigned g = sp.opening ? 1u : 2u;
      const std::size_t len = sp.x.size();
      bool any = false;
      for (std::size_t i = 0; i < k; ++i) {
        const bool in = (groups[pts[from + i]] & g) != 0u && static_cast<std::size_t>(3 * ms[i]) <= len;
        n_at[i] = in ? static_cast<double>(len) - 2.0 * static_cast<double>(ms[i]) + 1.0 : 0.0;
        pooled_terms[i] += n_at[i];
        any = any || in;
      }
      if (!any) continue;
      const std::vector<double> c = detail::overlapping_avar_cov(law, ms, len);
      for (std::size_t i = 0; i < k; ++i)
        for (std::size_t j = 0; j < k; ++j)
          cov(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j)) += n_at[i] * n_at[j] * c[i * k + j];
    }
    // The relative errors' covariance R (each estimate over the null law's value), the
    // deviance's weights P = edf / 4 (its near-law form, edf / 4 (y/m - 1)^2), the laws' relative
    // gradients: the walk's (tau / m) and the nuisance laws' in the null fit (1 / (tau m), 1 / m).
    Eigen::MatrixXd G(static_cast<Eigen::Index>(k), 3);
    Eigen::VectorXd P(static_cast<Eigen::Index>(k));
    for (std::size_t i = 0; i < k; ++i) {
      const auto r = static_cast<Eigen::Index>(i);
      const double m = law.at(ms[i]);
      if (!(m > 0.0) || !(pooled_terms[i] > 0.0)) return 1.0;
      for (std::size_t j = 0; j < k; ++j) {
        const auto c = static_cast<Eigen::Index>(j);
        cov(r, c) /= pooled_terms[i] * pooled_terms[j] * m * law.at(ms[j]);
      }
      P(r) = edf[pts[from + i]] / 4.0;
      G(r, 0) = base[from + i] / m;
      G(r, 1) = 1.0 / m;
      G(r, 2) = static_cast<double>(ms[i]) / m;
    }
    std::vector<Eigen::Index> nuisance;
    if (null.a > 0.0) nuisance.push_back(0);
    if (null.cf > 0.0) nuisance.push_back(1);
    Eigen::VectorXd h = G.col(2);
    if (!nuisance.empty()) {
      Eigen::MatrixXd Gn(static_cast<Eigen::Index>(k), static_cast<Eigen::Index>(nuisance.size()));
      for (std::size_t c = 0; c < nuisance.size(); ++c) Gn.col(static_cast<Eigen::Index>(c)) = G.col(nuisance[c]);
      const Eigen::MatrixXd A = Gn.transpose() * P.asDiagonal() * Gn;
      h -= Gn * A.ldlt().solve(Gn.transpose() * P.asDiagonal() * h);
    }
    const Eigen::VectorXd ph = P.asDiagonal() * h;
    const double assumed = h.dot(ph), actual = ph.dot(cov * ph);
    return assumed > 0.0 && actual > 0.0 && std::isfinite(actual) ? assumed / actual : 1.0;
  };
  // The deviance the long taus lose when a free walk is added to the laws refitted there, in
  // the units of a chi-square as the points' correlation allows (walk_dof_scale; the test a walk
  // must pass; 0 when the free walk comes out 0).
  auto long_walk_test = [&](std::size_t from) {
    const Sol without = solve(true, false, -1.0, from);
    const Sol with = solve(true, true, -1.0, from);
    if (!without.ok || !with.ok || with.cw <= 0.0) return 0.0;
    return fl.walk_test_dof_scale * (deviance(without, from) - deviance(with, from));
  };
  Sol best = solve(false, false), no_walk;
  double best_score = best.ok ? deviance(best) : std::numeric_limits<double>::infinity(), no_walk_score = best_score;
  if (best.ok) no_walk = best;
  for (auto [uf, uw] : {std::pair{true, false}, std::pair{false, true}, std::pair{true, true}}) {
    Sol s = solve(uf, uw);
    if (!s.ok) continue;
    // A law is paid for where it is in the solution (a coefficient held at 0 adds nothing).
    const double score = deviance(s) + o.min_chi2_gain * ((s.cf > 0.0) + (s.cw > 0.0));
    if (score < best_score) {
      best = s;
      best_score = score;
    }
    if (s.cw <= 0.0 && score < no_walk_score) {
      no_walk = s;
      no_walk_score = score;
    }
  }
  // The walk stays only when it earns its place at the taus where it is identifiable: on the
  // curve's last six octaves, the laws refitted there with a free walk lower the deviance by
  // walk_min_gain against the same laws without one (a likelihood-ratio test of one parameter,
  // the deviance counting each point's chi-square at half its degrees of freedom), or the walk
  // as read fits them no worse than no walk.
  // The whole curve's deviance cannot decide it: the short taus carry most of its degrees of
  // freedom, and where their shape is no law of the three (the simulator's flicker still rises
  // from 1 to ~10 s, a real FOG's short-term noise is no pure white noise either) a walk lowers
  // their misfit by bending it, and was read off a flat curve (9 of 40 seeds of 30 min holds at
  // 0.31-0.54 deg/h/sqrt(h), with the dominated taus only asked for no loss).
  fl.walk_test_dof_scale = walk_dof_scale(solve(true, false, -1.0, long_from), long_from);
  fl.walk_test_gain = long_walk_test(long_from);
  if (best.ok && best.cw > 0.0 && no_walk.ok) {
    // And over the taus where the walk as read is at least the law's other parts, the law with
    // it must fit no worse than the law without it: a walk that overshoots the long taus (the
    // curve flat there, the law rising) was read for the short taus' shape. A gain of
    // min_chi2_gain there lost most real walks of 0.1 deg/h/sqrt(h) in 30 min records (6 of 40
    // seen against 33 of 40); 0 keeps 30.
    double gain = 0.0;
    for (std::size_t q = 0; q < np; ++q)
      if (best.cw * static_cast<double>(sizes[pts[q]]) >= best.a * base[q] + best.cf) gain += point_deviance(no_walk, q) - point_deviance(best, q);
    // A walk the long taus neither ask for (a free walk there gains under walk_min_gain) nor
    // accept as read (held at the value read, the other laws refitted there, it fits them worse
    // than no walk) was read for the short taus' shape. Either alone keeps a real walk: where
    // white noise dominates all but the last few cluster times (a walk of 0.1 deg/h/sqrt(h)
    // under 0.6 deg/h of white, or in 30 min holds) the free walk's gain there is often small,
    // but the walk read off the whole curve fits those taus.
    fl.walk_read_gain = fl.walk_test_dof_scale * long_walk_gain(best.cw);
    if (gain < 0.0 || (fl.walk_test_gain < o.walk_min_gain && fl.walk_read_gain < o.walk_read_min_gain)) best = no_walk;
  }
  if (!best.ok) {
    fl.note = "the holds' Allan curve fits no noise law: the model's AR noise alone";
    return fl;
  }
  // With no slow law the floor is the model's AR noise, as before; with one, the white level
  // read off the curve stands for the short-term part.
  const double ar_std = ar_process_std(ar, sigma_a_dph);
  // A white level held at 0 (under what the curve resolves beside its slow laws) is kept a
  // hair above 0, since 0 there means the model's AR noise.
  if (best.cf > 0.0 || best.cw > 0.0) fl.white_var_dph2 = best.a > 0.0 ? best.a : 1e-12 * avar[pts.front()];
  fl.flicker_h = best.cf / (2.0 * std::numbers::ln2);
  fl.walk_h = best.cw * 3.0 / (2.0 * kPi * kPi);
  fl.bias_instability_dph = std::sqrt(kPi * fl.flicker_h);
  fl.rrw_dph_per_sqrt_h = 60.0 * std::sqrt(3.0 * best.cw);
  // The rate random walk the holds cannot exclude. A walk shows at long cluster times, and the
  // holds' stretches end at tau of a few minutes, where a walk that adds a run's worth of error
  // over hours (K sqrt(T / 6)) is still under the flicker or white level: undetected is not
  // absent. The bound is the largest walk whose profile deviance over the long taus (the other
  // laws refitted there at each value; long_walk_gain) rises by at most walk_bound_chi2 above
  // theirs without a walk: a profile over every tau let the walk bend the short-term part's
  // shape and ran the bound away with it. The rule (yardstick) allows for it in its limits, the
  // floor's own laws stay as read.
  // Read when flicker is seen and no walk (the case the holds leave ambiguous); with white noise
  // alone the AR rule stands.
  if (best.cw <= 0.0 && (best.cf > 0.0 || bound_always) && o.walk_bound_chi2 > 0.0) {
    // At a walk of cw, (deg/h)^2/s: how much more the long taus' deviance is with it (the other
    // laws refitted there) than without.
    auto excess_at = [&](double cw) { return -long_walk_gain(cw); };
    const double limit = o.walk_bound_chi2;
    double lo = 0.0;
    // A start from the longest cluster's variance read as walk alone, doubled until excluded.
    double hi = avar[pts.back()] / static_cast<double>(sizes[pts.back()]);
    int grow = 0;
    while (excess_at(hi) <= limit && grow++ < 60) hi *= 2.0;
    if (grow <= 60) {
      for (int it = 0; it < 50 && hi - lo > 1e-6 * hi; ++it) {
        const double mid = 0.5 * (lo + hi);
        (excess_at(mid) <= limit ? lo : hi) = mid;
      }
      fl.walk_bound_h = lo * 3.0 / (2.0 * kPi * kPi);
      fl.rrw_bound_dph_per_sqrt_h = 60.0 * std::sqrt(3.0 * lo);
    }
  }
  fl.note = "read on " + std::to_string(total) + " s of settled holds (" + std::to_string(spans.size()) + " stretches, tau up to " +
            fmt(fl.longest_tau_s, 0) + " s): white noise " + fmt(std::sqrt(best.a), 3) + " deg/h in 1 s (the model's AR noise " + fmt(ar_std, 3) + ")" +
            (fl.flicker_h > 0.0 ? ", bias instability " + fmt(fl.bias_instability_dph, 4) + " deg/h" : std::string()) +
            (fl.walk_h > 0.0 ? ", rate random walk " + fmt(fl.rrw_dph_per_sqrt_h, 4) + " deg/h/sqrt(h)" : std::string()) +
            (fl.slow() ? "" : ", no flicker or random walk seen") +
            (fl.walk_bound_h > 0.0 ? ", a rate random walk up to " + fmt(fl.rrw_bound_dph_per_sqrt_h, 4) + " deg/h/sqrt(h) not excluded" : std::string());
  return fl;
}

}  // namespace

NoiseFloor estimate_noise_floor(std::span<const FloorRun> runs, std::span<const double> ar, double sigma_a_dph, const NoiseFloorOptions& o) {
  std::vector<Stretch> spans;
  for (const auto& fr : runs) settled_stretches(fr, o, spans);
  if (spans.empty()) {
    NoiseFloor fl;
    fl.ar.assign(ar.begin(), ar.end());
    fl.sigma_a_dph = sigma_a_dph;
    fl.note = "no settled hold of " + std::to_string(o.min_stretch_s) + " s or more: the model's AR noise alone";
    return fl;
  }
  NoiseFloor fl = read_floor_laws(spans, ar, sigma_a_dph, o);
  if (!o.remove_creep) return fl;
  // The creep tested against the floor read on the holds as they are (the noise under no
  // creep); where it is taken out, the floor is read again on what is left.
  const CreepFit creep = remove_creep(spans, fl.slow() || fl.walk_bound_h > 0.0 ? fl : read_floor_laws(spans, ar, sigma_a_dph, o, true));
  if (creep.removed) {
    fl = read_floor_laws(spans, ar, sigma_a_dph, o);
    fl.creep_removed = true;
    fl.note += "; the thermistors' creep taken out of the holds (" + fmt(std::sqrt(creep.removed_var_dph2), 4) + " deg/h rms, Wald chi-square " +
               fmt(creep.chi2_eff, 1) + " against " + fmt(creep.quantile, 1) + ")";
  }
  fl.creep_chi2 = creep.chi2_eff;
  fl.creep_dof = creep.dof;
  return fl;
}

FloorVariance floor_variance(const NoiseFloor& f, std::size_t samples, int smooth_s) {
  // The run's residual about its mean in the cosine basis of a run of n samples (the
  // eigenfunctions of a demeaned random walk): ordinate k at f_k = k / (2n) Hz carries
  // S(f_k) |H(f_k)|^2 / (2n) of variance, one degree of freedom each.
  FloorVariance v;
  const std::size_t n = std::max<std::size_t>(2, samples);
  const double dn = 2.0 * static_cast<double>(n);
  double slow_var = 0.0;
  for (std::size_t k = 1; k < n; ++k) {
    const double fk = static_cast<double>(k) / dn;
    const double g = ma_gain2(smooth_s, fk) / dn;
    const double slow = (f.flicker_h / fk + f.walk_h / (fk * fk)) * g;
    const double fast = f.white_var_dph2 > 0.0 ? 2.0 * f.white_var_dph2 : ar_psd(f.ar, f.sigma_a_dph, fk);
    v.total += fast * g + slow;
    v.slow += slow;
    slow_var += 2.0 * slow * slow;
  }
  if (v.slow > 0.0 && slow_var > 0.0) {
    const double shape = v.slow * v.slow / slow_var, scale = slow_var / v.slow;
    v.slow_q99 = scale * gamma_quantile(shape, 0.99);
  }
  return v;
}

double slow_acf_allowance(const NoiseFloor& f, std::size_t samples) {
  // The slow noise is nearly constant over the whiteness test's lags: it lifts every
  // autocorrelation by its share of the run's variance, up to its 99th percentile. The walk the
  // holds cannot exclude counts in, as in the rule's other limits (yardstick).
  if (!f.slow()) return 0.0;
  const FloorVariance fv = floor_variance(with_walk_bound(f), samples, 1);
  const double rest = fv.total - fv.slow;
  return fv.slow_q99 > 0.0 ? fv.slow_q99 / (rest + fv.slow_q99) : 0.0;
}

NoiseFloor with_walk_bound(const NoiseFloor& f) {
  NoiseFloor b = f;
  b.walk_h += f.walk_bound_h;
  b.walk_bound_h = 0.0;
  b.rrw_bound_dph_per_sqrt_h = 0.0;
  return b;
}

std::string allowance_note(const NoiseFloor& f) {
  if (!(f.walk_bound_h > 0.0)) return {};
  return ", allowing for a rate random walk up to " + fmt(f.rrw_bound_dph_per_sqrt_h, 3) + " deg/h/sqrt(h) that the holds cannot exclude";
}

std::string noise_factor_reason(double comp_std_dph, double noise_std_dph, double factor, double limit_factor, const NoiseFloor& f) {
  return "compensated std " + fmt(comp_std_dph, 3) + " deg/h is " + fmt(factor, 2) + " x the gyro's noise std " + fmt(noise_std_dph, 3) +
         " deg/h (at most " + fmt(limit_factor, 2) + " x" + allowance_note(f) + ")";
}

std::expected<void, std::string> NoiseRule::validate() const {
  if (!(max_noise_factor >= 1.0 && max_noise_factor <= 100.0))
    return std::unexpected("the noise factor must be 1 to 100, got " + fmt(max_noise_factor, 3));
  if (!(k_sigma > 0.0)) return std::unexpected("k_sigma must be positive, got " + fmt(k_sigma, 3));
  if (!(k_slow >= 0.0)) return std::unexpected("k_slow must be 0 or more, got " + fmt(k_slow, 3));
  if (smooth_s < 1 || smooth_s % 2 == 0) return std::unexpected("smooth_s must be odd and positive, got " + std::to_string(smooth_s));
  if (!(max_fail_s >= 1.0 && max_fail_s <= 1e6)) return std::unexpected("the longest failing interval must be 1 s to 1e6 s, got " + fmt(max_fail_s, 1));
  if (!(floor.settle_s >= 0.0)) return std::unexpected("the floor's settle time must be 0 s or more");
  if (!(floor.walk_bound_chi2 >= 0.0 && floor.walk_bound_chi2 <= 100.0))
    return std::unexpected("the floor's walk_bound_chi2 must be 0 (no bound) to 100, got " + fmt(floor.walk_bound_chi2, 3));
  if (!(floor.walk_min_gain >= 0.0 && floor.walk_min_gain <= 100.0))
    return std::unexpected("the floor's walk_min_gain must be 0 to 100, got " + fmt(floor.walk_min_gain, 3));
  if (!(floor.walk_read_min_gain >= 0.0 && floor.walk_read_min_gain <= 100.0))
    return std::unexpected("the floor's walk_read_min_gain must be 0 to 100, got " + fmt(floor.walk_read_min_gain, 3));
  return {};
}

Yardstick yardstick(const RunData& run, std::span<const double> residual_dph, std::span<const double> weight, std::span<const double> ar,
                    double sigma_a_dph, std::size_t samples, const NoiseRule& rule) {
  Yardstick y;
  if (rule.given) {
    y.floor = *rule.given;
  } else if (rule.read_floor) {
    y.floor = estimate_noise_floor(run, residual_dph, weight, ar, sigma_a_dph, rule.floor);
  } else {
    y.floor.ar.assign(ar.begin(), ar.end());
    y.floor.sigma_a_dph = sigma_a_dph;
    y.floor.note = "the model's AR noise alone (no floor read)";
  }
  if (!y.floor.slow()) {
    // Exactly the AR rule: the AR process's std and k_sigma sigma_a.
    y.noise_std_dph = ar_process_std(ar, sigma_a_dph);
    y.limit_factor = rule.max_noise_factor;
    y.threshold_dph = rule.k_sigma * sigma_a_dph;
    return y;
  }
  const FloorVariance whole = floor_variance(y.floor, samples, 1);
  y.noise_std_dph = std::sqrt(whole.total);
  const double a = rule.k_sigma * std::max(sigma_a_dph, std::sqrt(y.floor.white_var_dph2));
  // The three limits of a floor's slow laws, against the floor's variance as read (V): the
  // compensated std may reach the 99th percentile of the run's variance (or max_noise_factor,
  // whichever allows more), a failing interval k_slow of the smoothed slow std beside the
  // short-term band, the whiteness test the slow part's 99th-percentile share.
  struct Limits {
    double factor, threshold, acf;
  };
  auto limits_of = [&](const NoiseFloor& f) {
    const FloorVariance w = floor_variance(f, samples, 1);
    const FloorVariance sm = floor_variance(f, samples, rule.smooth_s);
    const double q = (w.total - w.slow + w.slow_q99) / whole.total;
    return Limits{std::max(rule.max_noise_factor, std::sqrt(q)), std::sqrt(a * a + rule.k_slow * rule.k_slow * sm.slow), slow_acf_allowance(f, samples)};
  };
  NoiseFloor seen = y.floor;
  seen.walk_bound_h = 0.0;
  const Limits ls = limits_of(seen);
  y.limit_factor = ls.factor;
  y.threshold_dph = ls.threshold;
  y.acf_allowance = ls.acf;
  if (y.floor.walk_bound_h > 0.0) {
    // The walk the holds cannot exclude (seen slow noise makes the split between flicker and
    // walk ambiguous at the holds' cluster times) is allowed for, so that what the holds cannot
    // tell from the gyro's own noise is not called a missing effect: the threshold and the
    // whiteness allowance as for a seen walk (the limits of the floor with it added); the noise
    // factor's limit by the walk's mean variance over the run on top. Counting it there at its
    // 99th percentile, as a seen walk (max(limit, sqrt(Q / V))), cleared the grid's noise-factor
    // alarms at ARW 0.001, K 0.1 (2 of 20 -> 0) but lost detections of effects of the noise's
    // size on gyros with flicker (0.04*lp(T1,1600) 4 of 6 -> 0): the bound is wide on short
    // holds. docs/workbench.md "Whiteness and noise-factor alarms".
    const Limits lb = limits_of(with_walk_bound(y.floor));
    NoiseFloor walk;
    walk.walk_h = y.floor.walk_bound_h;
    const double w_whole = floor_variance(walk, samples, 1).slow;
    y.walk_allowance = true;
    y.limit_factor_seen = y.limit_factor;
    y.threshold_seen_dph = y.threshold_dph;
    y.acf_allowance_seen = y.acf_allowance;
    y.limit_factor = std::sqrt(y.limit_factor * y.limit_factor + w_whole / whole.total);
    y.threshold_dph = std::max(y.threshold_dph, lb.threshold);
    y.acf_allowance = std::max(y.acf_allowance, lb.acf);
  }
  return y;
}

}  // namespace fogbench::model
