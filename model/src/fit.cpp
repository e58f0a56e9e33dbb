// The two fitting methods (paper, joint), prediction, compensation and Table 1.
#include <Eigen/Dense>
#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <numeric>
#include <set>
#include <sstream>

#include "fogbench/model/model.hpp"
#include "lagscan.hpp"
#include "lsq.hpp"

namespace fogbench::model {
namespace {

using detail::LagScanner;
using detail::Lagged;
using detail::Spectrum;

std::unexpected<FitError> fail(FitError::Code c, std::string msg) { return std::unexpected(FitError{c, std::move(msg)}); }

// A fixed column of the regression: a view of a series (a term at its lag, read in place from
// its Lagged extension), or a constant (the intercept).
struct Column {
  const double* v = nullptr;  // null when constant; else valid for t = 0..N-1
  double c = 0.0;
  bool constant() const { return v == nullptr; }
  double at(std::size_t t) const { return v ? v[t] : c; }
};
Column lagged_view(const Lagged& x, int max_lag, int lag) {
  return {x.ext.data() + (max_lag - lag), 0.0};
}

struct ScanResult {
  int lag = 0;
  std::vector<double> theta;  // fixed columns first, then the varying ones
  double sse = std::numeric_limits<double>::infinity();
  bool ok = false;
};

// Least squares of y on [fixed columns, varying regressors all delayed by one shared lag i],
// for every i in [lo, hi]; returns the lag of least SSE.
ScanResult scan(const LagScanner& sc, std::span<const double> y, const Spectrum* wy_spec,
                const std::vector<Column>& fixed, const std::vector<const Lagged*>& varying, int lo, int hi) {
  const std::size_t n = sc.n();
  const auto& w = sc.weights();
  const std::size_t nf = fixed.size(), nv = varying.size(), k = nf + nv;
  std::vector<double> wy(n);
  double ywy = 0.0;
  for (std::size_t t = 0; t < n; ++t) {
    wy[t] = w[t] * y[t];
    ywy += wy[t] * y[t];
  }
  // The fixed block, F' W F and F' W y, summed pair by pair over the columns in place.
  Eigen::MatrixXd Gff(static_cast<Eigen::Index>(nf), static_cast<Eigen::Index>(nf));
  Eigen::VectorXd bf(static_cast<Eigen::Index>(nf));
  // sum_t w(t) u(t) v(t) for two columns (or w(t) v(t) with u constant, and so on).
  auto wdot = [&](const Column& u, const Column& v) {
    double sum = 0.0;
    if (u.constant() && v.constant()) {
      for (std::size_t t = 0; t < n; ++t) sum += w[t];
      return sum * u.c * v.c;
    }
    if (u.constant() || v.constant()) {
      const Column& x = u.constant() ? v : u;
      for (std::size_t t = 0; t < n; ++t) sum += w[t] * x.v[t];
      return sum * (u.constant() ? u.c : v.c);
    }
    for (std::size_t t = 0; t < n; ++t) sum += w[t] * u.v[t] * v.v[t];
    return sum;
  };
  for (std::size_t a = 0; a < nf; ++a) {
    double sb = 0.0;
    if (fixed[a].constant()) {
      for (std::size_t t = 0; t < n; ++t) sb += wy[t];
      sb *= fixed[a].c;
    } else {
      for (std::size_t t = 0; t < n; ++t) sb += fixed[a].v[t] * wy[t];
    }
    bf(static_cast<Eigen::Index>(a)) = sb;
    for (std::size_t c = a; c < nf; ++c)
      Gff(static_cast<Eigen::Index>(a), static_cast<Eigen::Index>(c)) = Gff(static_cast<Eigen::Index>(c), static_cast<Eigen::Index>(a)) =
          wdot(fixed[a], fixed[c]);
  }
  // Lag-dependent sums, each for all lags at once.
  std::vector<std::vector<double>> cvy(nv), gvv(nv * nv);
  std::vector<std::vector<std::vector<double>>> cvf(nv, std::vector<std::vector<double>>(nf));
  if (nv > 0) {
    Spectrum own;
    if (!wy_spec) {
      own = sc.spectrum_of_target(wy);
      wy_spec = &own;
    }
    std::vector<Spectrum> f_spec(nf);
    for (std::size_t a = 0; a < nf; ++a) {
      if (fixed[a].constant()) continue;
      std::vector<double> wf(n);
      for (std::size_t t = 0; t < n; ++t) wf[t] = w[t] * fixed[a].v[t];
      f_spec[a] = sc.spectrum_of_target(wf);
    }
    for (std::size_t v = 0; v < nv; ++v) {
      cvy[v] = sc.corr(*varying[v], *wy_spec);
      std::vector<double> ones_sum;
      for (std::size_t a = 0; a < nf; ++a) {
        if (fixed[a].constant()) {
          if (ones_sum.empty()) ones_sum = sc.wsum(varying[v]->ext);
          cvf[v][a] = ones_sum;
          for (double& s : cvf[v][a]) s *= fixed[a].c;
        } else {
          cvf[v][a] = sc.corr(*varying[v], f_spec[a]);
        }
      }
      for (std::size_t u = v; u < nv; ++u) {
        std::vector<double> prod(varying[v]->ext.size());
        for (std::size_t j = 0; j < prod.size(); ++j) prod[j] = varying[v]->ext[j] * varying[u]->ext[j];
        gvv[v * nv + u] = sc.wsum(prod);
      }
    }
  }
  ScanResult best;
  Eigen::MatrixXd G(k, k);
  Eigen::VectorXd b(k);
  if (nv == 0) lo = hi = 0;
  for (int i = lo; i <= hi; ++i) {
    const auto li = static_cast<std::size_t>(i);
    G.topLeftCorner(nf, nf) = Gff;
    b.head(nf) = bf;
    for (std::size_t v = 0; v < nv; ++v) {
      b(nf + v) = cvy[v][li];
      for (std::size_t a = 0; a < nf; ++a) G(a, nf + v) = G(nf + v, a) = cvf[v][a][li];
      for (std::size_t u = v; u < nv; ++u) G(nf + v, nf + u) = G(nf + u, nf + v) = gvv[v * nv + u][li];
    }
    Eigen::LDLT<Eigen::MatrixXd> ldlt(G);
    if (ldlt.info() != Eigen::Success || ldlt.rcond() < 1e-13) continue;
    const Eigen::VectorXd th = ldlt.solve(b);
    const double sse = ywy - b.dot(th);
    if (sse < best.sse) {
      best.sse = sse;
      best.lag = i;
      best.theta.assign(th.data(), th.data() + k);
      best.ok = true;
    }
  }
  return best;
}

// Least squares of y on fixed columns by the kernel (lsq.hpp): the coefficients and SSE the
// models report. The lag scan above picks lags from its normal equations (one solve per lag,
// every sum by FFT); the coefficients at the lags chosen come from here.
ScanResult solve_at(std::span<const double> y, std::span<const double> w, const std::vector<Column>& cols, int lag = 0) {
  detail::LeastSquares ls(cols.size());
  std::vector<double> row(cols.size());
  for (std::size_t t = 0; t < y.size(); ++t) {
    if (w[t] == 0.0) continue;
    for (std::size_t j = 0; j < cols.size(); ++j) row[j] = cols[j].at(t);
    ls.add(row, y[t], w[t]);
  }
  const detail::LeastSquaresResult r = ls.solve();
  ScanResult out;
  out.lag = lag;
  if (!r.ok) return out;
  out.theta = r.theta;
  out.sse = r.sse;
  out.ok = true;
  return out;
}


// AR(p) by least squares over the rows whose p+1 samples all have weight 1, accumulating
// the p x p normal equations in one pass (no design matrix: N is large, p is small).
std::expected<ArFit, std::string> fit_ar_rows(std::span<const double> e, std::span<const double> w, int p) {
  const auto pu = static_cast<std::size_t>(p);
  Eigen::MatrixXd XtX = Eigen::MatrixXd::Zero(p, p);
  Eigen::VectorXd XtY = Eigen::VectorXd::Zero(p);
  double yty = 0.0;
  std::size_t rows = 0;
  std::size_t run = 0;  // consecutive good samples ending at t
  std::vector<double> lagv(pu);
  for (std::size_t t = 0; t < e.size(); ++t) {
    run = w[t] != 0.0 ? run + 1 : 0;
    if (run <= pu) continue;
    for (std::size_t j = 0; j < pu; ++j) lagv[j] = e[t - 1 - j];
    for (std::size_t a = 0; a < pu; ++a) {
      XtY(static_cast<Eigen::Index>(a)) += lagv[a] * e[t];
      for (std::size_t b = a; b < pu; ++b) XtX(static_cast<Eigen::Index>(a), static_cast<Eigen::Index>(b)) += lagv[a] * lagv[b];
    }
    yty += e[t] * e[t];
    ++rows;
  }
  if (rows < 11 * pu) return std::unexpected("too few consecutive good samples for AR(" + std::to_string(p) + ")");
  XtX = XtX.selfadjointView<Eigen::Upper>();
  Eigen::LDLT<Eigen::MatrixXd> ldlt(XtX);
  if (ldlt.info() != Eigen::Success || ldlt.rcond() < 1e-14) return std::unexpected(std::string("degenerate residual series"));
  const Eigen::VectorXd th = ldlt.solve(XtY);
  ArFit r;
  r.k.assign(th.data(), th.data() + p);
  r.sigma_a2 = std::max(0.0, (yty - XtY.dot(th)) / static_cast<double>(rows));
  return r;
}

std::string fnv1a(const RunData& run) {
  std::uint64_t h = 1469598103934665603ull;
  // FNV-1a over 64-bit words rather than bytes: 8 times fewer steps, still a fingerprint.
  auto mix = [&](const std::vector<double>& v) {
    for (double d : v) {
      std::uint64_t bits;
      std::memcpy(&bits, &d, sizeof d);
      h = (h ^ bits) * 1099511628211ull;
    }
  };
  mix(run.gyro_dph);
  mix(run.t1_c);
  mix(run.t2_c);
  std::ostringstream o;
  o << std::hex << h;
  return o.str();
}

std::vector<double> weights_of(const RunData& run, std::size_t* flagged) {
  std::vector<double> w(run.size(), 1.0);
  std::size_t nf = 0;
  for (std::size_t t = 0; t < run.size(); ++t) {
    if (run.flagged(t) || !std::isfinite(run.gyro_dph[t])) {
      w[t] = 0.0;
      ++nf;
    }
  }
  if (flagged) *flagged = nf;
  return w;
}

std::expected<void, FitError> check_time(const RunData& run) {
  const std::size_t n = run.size();
  for (std::size_t t = 1; t < n; ++t) {
    const double dt = run.time_s[t] - run.time_s[t - 1];
    if (std::abs(dt - 1.0) > 0.01)
      return fail(FitError::Code::uneven_time,
                  "samples " + std::to_string(t) + " and " + std::to_string(t + 1) + " are " + std::to_string(dt) +
                      " s apart (at time_s " + std::to_string(run.time_s[t - 1]) +
                      "); the model works on 1 s samples: resample the run (fogctl --resample 1)");
  }
  return {};
}

// Names the terms that make the regression singular: those with weight in the null vector
// of the correlation matrix of the columns. Column j is read delayed by lags[j] samples (the
// first sample standing in before the start), so lagged columns need no copies; no lags, no
// delay.
std::expected<void, FitError> check_collinear(const std::vector<std::vector<double>>& cols,
                                              const std::vector<std::string>& names, std::span<const double> w,
                                              std::span<const std::size_t> lags = {}) {
  const std::size_t m = cols.size();
  if (m == 0) return {};
  const std::size_t n = w.size();
  // Column j at sample t is cols[j][t - lag_j], its first value before that; the sums below
  // take the few samples before the longest lag one by one, the rest as plain loops.
  std::vector<std::size_t> lag(m, 0);
  for (std::size_t j = 0; j < m && !lags.empty(); ++j) lag[j] = std::min(lags[j], n);
  const std::size_t head = m ? *std::max_element(lag.begin(), lag.end()) : 0;
  auto at = [&](std::size_t j, std::size_t t) { return cols[j][t >= lag[j] ? t - lag[j] : 0]; };
  const double sw = std::accumulate(w.begin(), w.end(), 0.0);
  std::vector<double> mean(m, 0.0), sd(m, 0.0);
  for (std::size_t j = 0; j < m; ++j) {
    double s = 0.0;
    for (std::size_t t = 0; t < head; ++t)
      if (w[t] != 0.0) s += w[t] * at(j, t);
    const double* x = cols[j].data();
    const std::size_t l = lag[j];
    for (std::size_t t = head; t < n; ++t) s += w[t] != 0.0 ? w[t] * x[t - l] : 0.0;
    mean[j] = s / sw;
  }
  // The centred cross products (two passes for accuracy: a term of large mean and small
  // spread loses nothing to cancellation); a weight of zero skips a sample, NaN and all.
  Eigen::MatrixXd C(static_cast<Eigen::Index>(m), static_cast<Eigen::Index>(m));
  for (std::size_t a = 0; a < m; ++a)
    for (std::size_t b = a; b < m; ++b) {
      double c = 0.0;
      for (std::size_t t = 0; t < head; ++t)
        if (w[t] != 0.0) c += w[t] * (at(a, t) - mean[a]) * (at(b, t) - mean[b]);
      const double* xa = cols[a].data();
      const double* xb = cols[b].data();
      const std::size_t la = lag[a], lb = lag[b];
      const double ma = mean[a], mb = mean[b];
      for (std::size_t t = head; t < n; ++t) c += w[t] != 0.0 ? w[t] * (xa[t - la] - ma) * (xb[t - lb] - mb) : 0.0;
      C(static_cast<Eigen::Index>(a), static_cast<Eigen::Index>(b)) = c;
    }
  for (std::size_t j = 0; j < m; ++j) {
    sd[j] = std::sqrt(C(static_cast<Eigen::Index>(j), static_cast<Eigen::Index>(j)) / sw);
    const double scale = std::max(1.0, std::abs(mean[j]));
    if (!(sd[j] > 1e-9 * scale))
      return fail(FitError::Code::collinear, "term '" + names[j] +
                                                 "' is constant over this run, so its coefficient cannot be told "
                                                 "from mu0: drop it or fit on a run where it varies");
  }
  Eigen::MatrixXd R(m, m);
  for (std::size_t a = 0; a < m; ++a)
    for (std::size_t b = a; b < m; ++b) {
      const double c = C(static_cast<Eigen::Index>(a), static_cast<Eigen::Index>(b));
      R(a, b) = R(b, a) = c / (sw * sd[a] * sd[b]);
    }
  auto min_eig = [](const Eigen::MatrixXd& M) {
    return M.rows() == 0 ? 1.0 : Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(M, Eigen::EigenvaluesOnly).eigenvalues()(0);
  };
  constexpr double singular = 1e-8;
  if (min_eig(R) > singular) return {};
  // A term takes part in the dependency when leaving it out makes the rest independent.
  std::string who;
  int count = 0;
  for (std::size_t j = 0; j < m; ++j) {
    Eigen::MatrixXd S(m - 1, m - 1);
    for (std::size_t a = 0, ra = 0; a < m; ++a) {
      if (a == j) continue;
      for (std::size_t b = 0, rb = 0; b < m; ++b) {
        if (b == j) continue;
        S(static_cast<Eigen::Index>(ra), static_cast<Eigen::Index>(rb)) = R(static_cast<Eigen::Index>(a), static_cast<Eigen::Index>(b));
        ++rb;
      }
      ++ra;
    }
    if (min_eig(S) > singular) {
      who += (count ? ", '" : "'") + names[j] + "'";
      ++count;
    }
  }
  if (count == 0) who = "(several groups of)";
  return fail(FitError::Code::collinear, "terms " + who + " are collinear on this run (one is a combination of the "
                                         "others), so their coefficients cannot be separated: drop one of them");
}

}  // namespace

std::string_view to_string(Method m) { return m == Method::paper ? "paper" : "joint"; }
std::optional<Method> method_from_string(std::string_view s) {
  if (s == "paper") return Method::paper;
  if (s == "joint") return Method::joint;
  return std::nullopt;
}

std::string_view to_string(FitError::Code c) {
  switch (c) {
    case FitError::Code::bad_options: return "bad_options";
    case FitError::Code::too_short: return "too_short";
    case FitError::Code::bad_term: return "bad_term";
    case FitError::Code::missing_signal: return "missing_signal";
    case FitError::Code::collinear: return "collinear";
    case FitError::Code::degenerate: return "degenerate";
    case FitError::Code::uneven_time: return "uneven_time";
  }
  return "unknown";
}

std::string term_key(const Term& t) { return to_string(*t.expr); }

std::string Model::terms_string() const {
  std::string s;
  for (const auto& t : terms) {
    if (!s.empty()) s += " + ";
    s += t.name();
    if (t.term.lag.seconds || t.term.lag.automatic) s += "@" + std::to_string(t.term.lag.seconds);
  }
  return s.empty() ? "(constant)" : s;
}

std::expected<void, std::string> FitOptions::validate() const {
  if (ar_order < 1 || ar_order > 10) return std::unexpected("ar_order must be 1..10, got " + std::to_string(ar_order));
  if (max_lag_s < 0 || max_lag_s > 7200) return std::unexpected("max_lag_s must be 0..7200 s, got " + std::to_string(max_lag_s));
  if (smooth_s < 1 || smooth_s % 2 == 0) return std::unexpected("smooth_s must be a positive odd number of seconds, got " + std::to_string(smooth_s));
  if (hold_s < 60) return std::unexpected("hold_s must be at least 60 s, got " + std::to_string(hold_s));
  if (!(outlier_sigma >= 2.0)) return std::unexpected("outlier_sigma must be at least 2, got " + std::to_string(outlier_sigma));
  if (max_iterations < 1) return std::unexpected(std::string("max_iterations must be at least 1"));
  if (!(tolerance > 0.0)) return std::unexpected(std::string("tolerance must be positive"));
  if (!std::isfinite(tref_c)) return std::unexpected(std::string("tref_c must be a finite temperature in degC"));
  return {};
}

std::expected<RunSignals, FitError> run_signals(const RunData& run, double tref_c) {
  const std::size_t n = run.size();
  RunSignals s;
  s.t1.resize(n);
  s.t2.resize(n);
  auto bridge = [&](const std::vector<double>& src, std::vector<double>& dst, const char* what) -> std::expected<void, FitError> {
    // Good samples: finite and, when flags are recorded, not flagged missing/out of range.
    auto good = [&](std::size_t t) {
      return std::isfinite(src[t]) && !(run.has_flags() && (run.flags[t] & (flag::missing | flag::out_of_range)));
    };
    std::size_t last = n;
    for (std::size_t t = 0; t < n; ++t) {
      if (!good(t)) continue;
      dst[t] = src[t] - tref_c;
      if (last == n) {
        for (std::size_t u = 0; u < t; ++u) dst[u] = dst[t];
      } else if (t > last + 1) {
        for (std::size_t u = last + 1; u < t; ++u)
          dst[u] = dst[last] + (dst[t] - dst[last]) * static_cast<double>(u - last) / static_cast<double>(t - last);
      }
      last = t;
    }
    if (last == n) return fail(FitError::Code::missing_signal, std::string("the run has no valid ") + what + " sample");
    for (std::size_t u = last + 1; u < n; ++u) dst[u] = dst[last];
    return {};
  };
  if (auto r = bridge(run.t1_c, s.t1, "T1 (t1_c)"); !r) return std::unexpected(r.error());
  if (auto r = bridge(run.t2_c, s.t2, "T2 (t2_c)"); !r) return std::unexpected(r.error());
  if (run.has_chamber()) {
    s.ta.resize(n);
    if (auto r = bridge(run.chamber_c, s.ta, "Ta (chamber_c)"); !r) return std::unexpected(r.error());
  }
  // Time since power-on is a clock, not a reading: taken as recorded (not offset by Tref, not
  // bridged); a run without it leaves it empty and a term using it says so.
  if (run.has_power_on() && run.since_power_on_s.size() == n) s.ton = run.since_power_on_s;
  return s;
}

namespace {

struct Evaluated {
  RunSignals sig;
  std::vector<std::vector<double>> x;  // each term, unlagged
  std::vector<std::string> names;
};

std::expected<Evaluated, FitError> evaluate_terms(const RunData& run, const std::vector<Term>& terms, double tref_c) {
  Evaluated ev;
  auto s = run_signals(run, tref_c);
  if (!s) return std::unexpected(s.error());
  ev.sig = std::move(*s);
  for (const auto& t : terms) {
    auto v = evaluate(*t.expr, ev.sig.view());
    if (!v) return fail(FitError::Code::missing_signal, "term '" + to_string(t, false) + "': " + v.error());
    ev.x.push_back(std::move(*v));
    ev.names.push_back(to_string(t, false));
  }
  return ev;
}

// Standard errors and coefficient correlations from the prewhitened design, and the BIC of
// the innovations: common to both methods so that models compare on one footing.
void finish_stats(Model& m, const Evaluated& ev, std::span<const double> y, std::span<const double> w0, int n_auto_lags) {
  const std::size_t n = y.size();
  const std::size_t nt = m.terms.size();
  const std::size_t p = m.ar.size();
  double ksum = 0.0;
  for (double k : m.ar) ksum += k;
  const std::size_t k = 1 + nt;
  // One pass over the run, no arrays of its length: the prewhitened design row
  // [1 - sum k, (1 - k(q)) x_j(t - lag_j)] and residual a(t) = (1 - k(q)) e(t), with
  // e = y - mu0 - sum coef_j x_j(t - lag_j), are formed sample by sample (values before the
  // start equal to the first, as ar_filter takes them) and streamed into the kernel's QR
  // (the covariance s2 (X' W X)^-1 from its triangle) and the RSS. A sample counts when it
  // and the p before it all have weight.
  std::vector<std::size_t> lag(nt);
  for (std::size_t j = 0; j < nt; ++j) lag[j] = static_cast<std::size_t>(m.terms[j].term.lag.seconds);
  auto x_at = [&](std::size_t j, std::size_t t, std::size_t back) {  // x_j(t - back - lag_j), clamped at 0
    const std::size_t d = back + lag[j];
    return ev.x[j][t >= d ? t - d : 0];
  };
  auto e_at = [&](std::size_t u) {  // the trend residual at sample u
    double trend = m.mu0_dph;
    for (std::size_t j = 0; j < nt; ++j) trend += m.terms[j].coef * x_at(j, u, 0);
    return y[u] - trend;
  };
  // e(t), e(t-1), ..., e(t-p), kept as t advances (each e computed once).
  std::vector<double> e_recent(p + 1);
  for (std::size_t i = 0; i <= p && p < n; ++i) e_recent[i] = e_at(p - i);
  detail::LeastSquares ls(k);  // the prewhitened design's R, for (X' W X)^-1 without forming X' W X
  std::vector<double> row(k);
  row[0] = 1.0 - ksum;
  double rss = 0.0, nw = 0.0;
  for (std::size_t t = p; t < n; ++t) {
    if (t > p) {
      for (std::size_t i = p; i > 0; --i) e_recent[i] = e_recent[i - 1];
      e_recent[0] = e_at(t);
    }
    bool ok = true;
    for (std::size_t j = 0; j <= p && ok; ++j) ok = w0[t - j] != 0.0;
    if (!ok) continue;
    for (std::size_t j = 0; j < nt; ++j) {
      double f = x_at(j, t, 0);
      for (std::size_t i = 0; i < p; ++i) f -= m.ar[i] * x_at(j, t, i + 1);
      row[j + 1] = f;
    }
    double a = e_recent[0];
    for (std::size_t i = 0; i < p; ++i) a -= m.ar[i] * e_recent[i + 1];
    ls.add(row, 0.0);
    rss += a * a;
    nw += 1.0;
  }
  const double nparams = static_cast<double>(k + p + static_cast<std::size_t>(n_auto_lags));
  const double s2 = nw > nparams ? rss / (nw - nparams) : 0.0;
  m.fit.coef_corr.assign(k, std::vector<double>(k, 0.0));
  if (const Eigen::MatrixXd cov = ls.covariance(s2); cov.size() != 0) {
    m.mu0_se = std::sqrt(std::max(0.0, cov(0, 0)));
    for (std::size_t j = 0; j < nt; ++j) m.terms[j].se = std::sqrt(std::max(0.0, cov(j + 1, j + 1)));
    for (std::size_t r = 0; r < k; ++r)
      for (std::size_t c = 0; c < k; ++c) {
        const double d = std::sqrt(cov(r, r) * cov(c, c));
        m.fit.coef_corr[r][c] = d > 0.0 ? cov(r, c) / d : (r == c ? 1.0 : 0.0);
      }
  }
  m.fit.bic = nw > 0 && rss > 0 ? nw * std::log(rss / nw) + nparams * std::log(nw) : 0.0;
}

void fill_fitted_on(Model& m, const RunData& run) {
  m.fitted_on.name = run.name;
  m.fitted_on.n_samples = run.size();
  m.fitted_on.duration_s = run.size() ? run.time_s.back() - run.time_s.front() + 1.0 : 0.0;
  if (!run.t1_c.empty()) {
    auto [lo, hi] = std::minmax_element(run.t1_c.begin(), run.t1_c.end());
    m.fitted_on.t1_min_c = *lo;
    m.fitted_on.t1_max_c = *hi;
  }
  m.fitted_on.fingerprint = fnv1a(run);
}

// The opening hold: the first hold phase (or constant setpoint, or simply the start), at most hold_s.
std::pair<std::size_t, std::size_t> opening_hold(const RunData& run, int hold_s) {
  const std::size_t n = run.size();
  const auto cap = static_cast<std::size_t>(hold_s);
  std::size_t b = 0;
  if (run.has_phase()) {
    while (b < n && run.phase[b] != Phase::hold) ++b;
    if (b == n) b = 0;
    std::size_t e = b;
    while (e < n && e - b < cap && run.phase[e] == Phase::hold) ++e;
    if (e > b) return {b, e};
  }
  if (run.has_setpoint()) {
    std::size_t e = 0;
    while (e < n && e < cap && std::abs(run.setpoint_c[e] - run.setpoint_c[0]) < 0.01) ++e;
    return {0, e};
  }
  return {0, std::min(n, cap)};
}

std::expected<Model, FitError> fit_paper(const RunData& run, const std::vector<Term>& terms, const FitOptions& o,
                                         const Evaluated& ev, std::vector<double> w) {
  Model m;
  m.method = Method::paper;
  m.shared_lag = true;
  const std::size_t n = run.size();
  const int L = o.max_lag_s;
  // Step 1: the opening hold gives mu0 and the AR noise.
  auto [hb, he] = opening_hold(run, o.hold_s);
  std::vector<double> hold;
  for (std::size_t t = hb; t < he; ++t)
    if (w[t] != 0.0) hold.push_back(run.gyro_dph[t]);
  if (hold.size() < 60)
    return fail(FitError::Code::too_short, "the opening hold has " + std::to_string(hold.size()) +
                                               " good samples; the paper method needs at least 60 s of constant "
                                               "temperature at the start of the run to estimate mu0 and the AR noise");
  const OutlierResult out = outliers_3sigma(hold, o.outlier_sigma);
  std::vector<double> kept;
  for (std::size_t i = 0; i < hold.size(); ++i)
    if (out.keep[i]) kept.push_back(hold[i]);
  m.mu0_dph = mean(kept);
  for (double& v : kept) v -= m.mu0_dph;
  const StationarityResult st = stationarity_check(kept);
  auto ar = fit_ar(kept, o.ar_order);
  if (!ar) return fail(FitError::Code::too_short, "opening hold: " + ar.error());
  m.ar = ar->k;
  m.sigma_a_dph = std::sqrt(ar->sigma_a2);
  const Whiteness wh = whiteness(ar->residuals, 20, o.ar_order);
  m.fit.n_hold = hold.size();
  m.fit.stationary = st.stationary;
  m.fit.ljung_box_q = wh.lb.q;
  m.fit.ljung_box_p = wh.lb.p_value;
  // Step 2: the trend of the smoothed output. Outliers (3 sigma about the smooth) are
  // removed from the smoothing, then the smoothed series is regressed on the terms.
  std::vector<double> s = moving_average(run.gyro_dph, w, o.smooth_s);
  {
    std::vector<double> r, idx;
    for (std::size_t t = 0; t < n; ++t)
      if (w[t] != 0.0) r.push_back(run.gyro_dph[t] - s[t]);
    const OutlierResult ro = outliers_3sigma(r, o.outlier_sigma);
    std::vector<double> ws = w;
    std::size_t j = 0;
    for (std::size_t t = 0; t < n; ++t)
      if (w[t] != 0.0 && !ro.keep[j++]) ws[t] = 0.0;
    m.fit.n_outliers = ro.removed + out.removed;
    if (ro.removed) s = moving_average(run.gyro_dph, ws, o.smooth_s);
  }
  std::vector<double> z(n);
  for (std::size_t t = 0; t < n; ++t) z[t] = s[t] - m.mu0_dph;
  std::vector<Lagged> lagged;
  for (const auto& x : ev.x) lagged.push_back(detail::make_lagged(x, L));
  std::vector<Column> fixed;
  std::vector<const Lagged*> varying;
  std::vector<std::size_t> fixed_idx, var_idx;
  for (std::size_t j = 0; j < terms.size(); ++j) {
    if (terms[j].lag.automatic) {
      varying.push_back(&lagged[j]);
      var_idx.push_back(j);
    } else {
      if (terms[j].lag.seconds > L)
        return fail(FitError::Code::bad_options, "term '" + ev.names[j] + "' has lag " + std::to_string(terms[j].lag.seconds) +
                                                     " s, beyond the maximum lag of " + std::to_string(L) + " s");
      fixed.push_back(lagged_view(lagged[j], L, terms[j].lag.seconds));
      fixed_idx.push_back(j);
    }
  }
  LagScanner sc(n, L, w);
  const ScanResult best = scan(sc, z, nullptr, fixed, varying, 0, L);
  if (!best.ok) return fail(FitError::Code::degenerate, "no lag in 0.." + std::to_string(L) + " s gives a solvable regression");
  // The coefficients at the lag chosen, by the kernel (fixed columns first, as the scan orders them).
  std::vector<Column> all = fixed;
  for (const Lagged* v : varying) all.push_back(lagged_view(*v, L, best.lag));
  const ScanResult r = solve_at(z, w, all, best.lag);
  if (!r.ok) return fail(FitError::Code::degenerate, "the regression is singular at lag " + std::to_string(best.lag) + " s");
  m.terms.resize(terms.size());
  for (std::size_t a = 0; a < fixed_idx.size(); ++a) {
    m.terms[fixed_idx[a]].term = terms[fixed_idx[a]];
    m.terms[fixed_idx[a]].coef = r.theta[a];
  }
  for (std::size_t v = 0; v < var_idx.size(); ++v) {
    auto& ft = m.terms[var_idx[v]];
    ft.term = terms[var_idx[v]];
    ft.term.lag.seconds = r.lag;
    ft.coef = r.theta[fixed_idx.size() + v];
  }
  double zz = 0.0, zm = 0.0, sw = 0.0;
  for (std::size_t t = 0; t < n; ++t) {
    zm += w[t] * z[t];
    sw += w[t];
  }
  zm /= sw;
  for (std::size_t t = 0; t < n; ++t) zz += w[t] * (z[t] - zm) * (z[t] - zm);
  m.fit.rss = r.sse;
  m.fit.trend_r2 = zz > 0.0 ? 1.0 - r.sse / zz : 0.0;
  m.fit.n_used = static_cast<std::size_t>(sw);
  finish_stats(m, ev, run.gyro_dph, w, varying.empty() ? 0 : 1);
  return m;
}

std::expected<Model, FitError> fit_joint(const RunData& run, const std::vector<Term>& terms, const FitOptions& o,
                                         const Evaluated& ev, std::vector<double> w) {
  Model m;
  m.method = Method::joint;
  const std::size_t n = run.size();
  const std::size_t nt = terms.size();
  const int L = o.max_lag_s;
  const int p = o.ar_order;
  // Outliers are replaced by the OLS fit (their residual set to zero) rather than given zero
  // weight: the weights stay a range with few holes, so every lag sum is a prefix sum.
  std::vector<double> y_clean(run.gyro_dph);
  const std::span<const double> y = y_clean;
  std::vector<int> lag(nt);
  int n_auto = 0;
  for (std::size_t j = 0; j < nt; ++j) {
    lag[j] = terms[j].lag.automatic ? 0 : terms[j].lag.seconds;
    n_auto += terms[j].lag.automatic;
    if (lag[j] > L)
      return fail(FitError::Code::bad_options, "term '" + ev.names[j] + "' has lag " + std::to_string(lag[j]) +
                                                   " s, beyond the maximum lag of " + std::to_string(L) + " s");
  }
  std::vector<double> theta(nt + 1, 0.0);  // mu0', betas
  bool first_pass = true;
  std::vector<double> k(static_cast<std::size_t>(p), 0.0);

  // One pass of coordinate descent on the lags of the @auto terms, for the regression of
  // yf on [c, xf_j(t - lag_j)], where yf, xf are the (prewhitened) series. Returns whether
  // any lag moved; theta is updated.
  auto solve = [&](const LagScanner& sc, std::span<const double> yf, const std::vector<Lagged>& xf, double c,
                   bool move_lags, int max_sweeps = 6) -> std::expected<bool, FitError> {
    Spectrum wy_spec;
    if (move_lags && n_auto > 0) {
      std::vector<double> wy(n);
      for (std::size_t t = 0; t < n; ++t) wy[t] = sc.weights()[t] * yf[t];
      wy_spec = sc.spectrum_of_target(wy);
      // Start from one lag shared by all @auto terms (one scan), then refine each.
      if (first_pass) {
        std::vector<Column> fixed{{nullptr, c}};
        std::vector<const Lagged*> var;
        for (std::size_t l = 0; l < nt; ++l) {
          if (terms[l].lag.automatic) var.push_back(&xf[l]);
          else fixed.push_back(lagged_view(xf[l], L, lag[l]));
        }
        const ScanResult r = scan(sc, yf, &wy_spec, fixed, var, 0, L);
        if (r.ok)
          for (std::size_t l = 0; l < nt; ++l)
            if (terms[l].lag.automatic) lag[l] = r.lag;
        first_pass = false;
      }
    }
    bool moved = false;
    for (int sweep = 0; sweep < max_sweeps && move_lags; ++sweep) {
      bool moved_now = false;
      for (std::size_t j = 0; j < nt && move_lags; ++j) {
        if (!terms[j].lag.automatic) continue;
        std::vector<Column> fixed{{nullptr, c}};
        for (std::size_t l = 0; l < nt; ++l)
          if (l != j) fixed.push_back(lagged_view(xf[l], L, lag[l]));
        const ScanResult r = scan(sc, yf, &wy_spec, fixed, {&xf[j]}, 0, L);
        if (!r.ok) return fail(FitError::Code::degenerate, "term '" + ev.names[j] + "': no lag gives a solvable regression");
        if (r.lag != lag[j]) moved_now = moved = true;
        lag[j] = r.lag;
      }
      if (!moved_now || !move_lags) break;
    }
    std::vector<Column> all{{nullptr, c}};
    for (std::size_t l = 0; l < nt; ++l) all.push_back(lagged_view(xf[l], L, lag[l]));
    const ScanResult r = solve_at(yf, sc.weights(), all);
    if (!r.ok) return fail(FitError::Code::degenerate, "the regression is singular at the chosen lags");
    theta = r.theta;
    m.fit.rss = r.sse;
    return moved;
  };

  auto residual = [&](std::vector<double>& e) {
    e.assign(y.begin(), y.end());
    for (std::size_t t = 0; t < n; ++t) {
      e[t] -= theta[0];
      for (std::size_t j = 0; j < nt; ++j) {
        const auto lj = static_cast<std::size_t>(lag[j]);
        e[t] -= theta[j + 1] * ev.x[j][t >= lj ? t - lj : 0];
      }
    }
  };

  // Ordinary least squares first (white errors), then the outliers of its residual.
  std::vector<Lagged> xl;
  for (const auto& x : ev.x) xl.push_back(detail::make_lagged(x, L));
  {
    // Only the shared-lag start here: the lags are refined once the noise is whitened.
    LagScanner sc(n, L, w);
    auto r = solve(sc, y, xl, 1.0, true, /*sweeps=*/0);
    if (!r) return std::unexpected(r.error());
  }
  std::vector<double> e;
  residual(e);
  {
    std::vector<double> r;
    for (std::size_t t = 0; t < n; ++t)
      if (w[t] != 0.0) r.push_back(e[t]);
    const OutlierResult ro = outliers_3sigma(r, o.outlier_sigma);
    std::size_t j = 0;
    for (std::size_t t = 0; t < n; ++t)
      if (w[t] != 0.0 && !ro.keep[j++]) {
        y_clean[t] -= e[t];
        e[t] = 0.0;
      }
    m.fit.n_outliers = ro.removed;
  }
  // Cochrane-Orcutt: AR(p) of the residual, prewhiten, refit (lags included), until stable.
  bool converged = false;
  bool search_lags = true;
  std::vector<double> k_at_search(static_cast<std::size_t>(p), 0.0);
  int it = 0;
  std::vector<double> wf(n);
  for (; it < o.max_iterations && !converged; ++it) {
    auto ar = fit_ar_rows(e, w, p);
    if (!ar) return fail(FitError::Code::too_short, "joint fit: " + ar.error());
    const std::vector<double> k_new = ar->k;
    double ksum = 0.0;
    for (double v : k_new) ksum += v;
    for (std::size_t t = 0; t < n; ++t) {
      bool ok = t >= static_cast<std::size_t>(p);
      for (int j = 0; j <= p && ok; ++j) ok = w[t - static_cast<std::size_t>(j)] != 0.0;
      wf[t] = ok ? 1.0 : 0.0;
    }
    const std::vector<double> yf = ar_filter(y, k_new);
    std::vector<Lagged> xf;
    for (const auto& x : xl) xf.push_back(Lagged{ar_filter(x.ext, k_new), {}});
    const std::vector<double> old = theta;
    const std::vector<int> old_lag = lag;
    LagScanner sc(n, L, wf);
    // Lags move little once the noise is whitened: search them on the first iteration and
    // whenever the coefficients have settled (to confirm), not on every iteration.
    auto r = solve(sc, yf, xf, 1.0 - ksum, search_lags);
    if (!r) return std::unexpected(r.error());
    // The intercept of the prewhitened regression is mu0 itself (its column is 1 - sum k).
    double change = 0.0;
    for (std::size_t j = 0; j <= nt; ++j) change = std::max(change, std::abs(theta[j] - old[j]) / std::max(1e-6, std::abs(theta[j])));
    for (std::size_t j = 0; j < k.size(); ++j) change = std::max(change, std::abs(k_new[j] - k[j]));
    // Confirm the lags once the coefficients have settled, unless the whitening has barely
    // changed since they were searched (AR coefficients within 0.01: the lag sums differ by
    // less than the noise).
    double k_drift = 0.0;
    for (std::size_t j = 0; j < k_new.size(); ++j) k_drift = std::max(k_drift, std::abs(k_new[j] - k_at_search[j]));
    if (search_lags) k_at_search = k_new;
    k = k_new;
    const bool settled = change < o.tolerance && lag == old_lag;
    converged = settled && (search_lags || n_auto == 0 || k_drift < 0.01);
    search_lags = settled && !converged;
    residual(e);
    double rss = 0.0, cnt = 0.0;
    const std::vector<double> a = ar_filter(e, k);
    for (std::size_t t = 0; t < n; ++t)
      if (wf[t] != 0.0) {
        rss += a[t] * a[t];
        cnt += 1.0;
      }
    m.sigma_a_dph = std::sqrt(rss / std::max(1.0, cnt));
    m.fit.n_used = static_cast<std::size_t>(cnt);
  }
  m.fit.iterations = it;
  m.fit.converged = converged;
  m.ar = k;
  m.mu0_dph = theta[0];
  m.terms.resize(nt);
  for (std::size_t j = 0; j < nt; ++j) {
    m.terms[j].term = terms[j];
    m.terms[j].term.lag.seconds = lag[j];
    m.terms[j].coef = theta[j + 1];
  }
  {
    std::vector<double> a = ar_filter(e, k), aw;
    for (std::size_t t = 0; t < n; ++t)
      if (wf[t] != 0.0) aw.push_back(a[t]);
    const LjungBox lb = ljung_box(aw, 20, p);
    m.fit.ljung_box_q = lb.q;
    m.fit.ljung_box_p = lb.p_value;
    double ym = 0.0, sw = 0.0, yy = 0.0, ee = 0.0;
    for (std::size_t t = 0; t < n; ++t)
      if (w[t] != 0.0) {
        ym += y[t];
        sw += 1.0;
      }
    ym /= sw;
    for (std::size_t t = 0; t < n; ++t)
      if (w[t] != 0.0) {
        yy += (y[t] - ym) * (y[t] - ym);
        ee += e[t] * e[t];
      }
    m.fit.trend_r2 = yy > 0.0 ? 1.0 - ee / yy : 0.0;
  }
  finish_stats(m, ev, y, w, n_auto);
  return m;
}

}  // namespace

std::expected<Model, FitError> fit(const RunData& run, const TermList& tl, const FitOptions& o) {
  if (auto v = o.validate(); !v) return fail(FitError::Code::bad_options, v.error());
  const std::size_t n = run.size();
  if (run.gyro_dph.size() != n || run.t1_c.size() != n || run.t2_c.size() != n)
    return fail(FitError::Code::bad_options, "the run's columns have different lengths");
  std::vector<Term> terms = tl.terms;
  // The same term twice (at any lag) cannot be separated unless both lags are fixed and differ.
  for (std::size_t a = 0; a < terms.size(); ++a)
    for (std::size_t b = a + 1; b < terms.size(); ++b)
      if (term_key(terms[a]) == term_key(terms[b]) &&
          (terms[a].lag.automatic || terms[b].lag.automatic || terms[a].lag.seconds == terms[b].lag.seconds) &&
          !(o.method == Method::joint && terms[a].lag.automatic && terms[b].lag.automatic))
        return fail(FitError::Code::collinear, "term '" + term_key(terms[a]) + "' appears twice at the same lag");
  const std::size_t min_n = static_cast<std::size_t>(o.max_lag_s) + 20 * (terms.size() + static_cast<std::size_t>(o.ar_order) + 1) + 60;
  if (n < min_n)
    return fail(FitError::Code::too_short, "the run has " + std::to_string(n) + " samples, too short for lags up to " +
                                               std::to_string(o.max_lag_s) + " s and " + std::to_string(terms.size()) +
                                               " terms: at least " + std::to_string(min_n) +
                                               " are needed (or lower the maximum lag)");
  if (auto t = check_time(run); !t) return std::unexpected(t.error());
  auto ev = evaluate_terms(run, terms, o.tref_c);
  if (!ev) return std::unexpected(ev.error());
  std::size_t n_flagged = 0;
  std::vector<double> w = weights_of(run, &n_flagged);
  if (auto c = check_collinear(ev->x, ev->names, w); !c) return std::unexpected(c.error());
  // A reading not taken (NaN) has weight 0, but 0 * NaN is NaN: give it a finite value that
  // no sum will see.
  const RunData* src = &run;
  RunData clean;
  if (std::any_of(run.gyro_dph.begin(), run.gyro_dph.end(), [](double v) { return !std::isfinite(v); })) {
    clean = run;
    for (double& v : clean.gyro_dph)
      if (!std::isfinite(v)) v = 0.0;
    src = &clean;
  }
  auto m = o.method == Method::paper ? fit_paper(*src, terms, o, *ev, w) : fit_joint(*src, terms, o, *ev, w);
  if (!m) return m;
  // A pair of @auto terms that are collinear only at their fitted lags is caught here.
  {
    std::vector<std::size_t> lags;
    std::vector<std::string> lagged_names;
    for (std::size_t j = 0; j < terms.size(); ++j) {
      lags.push_back(static_cast<std::size_t>(m->terms[j].term.lag.seconds));
      lagged_names.push_back(ev->names[j] + "@" + std::to_string(m->terms[j].term.lag.seconds));
    }
    if (auto c = check_collinear(ev->x, lagged_names, w, lags); !c) return std::unexpected(c.error());
  }
  m->fit.n_flagged = n_flagged;
  m->tref_c = o.tref_c;
  m->max_lag_s = o.max_lag_s;
  m->smooth_s = o.smooth_s;
  m->hold_s = o.hold_s;
  fill_fitted_on(*m, run);
  return m;
}

std::expected<std::vector<std::vector<double>>, FitError> regressors(const Model& m, const RunData& run) {
  std::vector<Term> terms;
  for (const auto& t : m.terms) terms.push_back(t.term);
  auto ev = evaluate_terms(run, terms, m.tref_c);
  if (!ev) return std::unexpected(ev.error());
  const std::size_t n = run.size();
  std::vector<std::vector<double>> cols;
  for (std::size_t j = 0; j < terms.size(); ++j) {
    const auto lag = static_cast<std::size_t>(m.terms[j].term.lag.seconds);
    std::vector<double> c(n);
    for (std::size_t t = 0; t < n; ++t) c[t] = ev->x[j][t >= lag ? t - lag : 0];
    cols.push_back(std::move(c));
  }
  return cols;
}

std::expected<std::vector<double>, FitError> predict(const Model& m, const RunData& run) {
  auto cols = regressors(m, run);
  if (!cols) return std::unexpected(cols.error());
  std::vector<double> mu(run.size(), m.mu0_dph);
  for (std::size_t j = 0; j < cols->size(); ++j)
    for (std::size_t t = 0; t < mu.size(); ++t) mu[t] += m.terms[j].coef * (*cols)[j][t];
  return mu;
}

Table1 table1(std::span<const double> y, std::span<const double> mu) {
  Table1 r;
  r.n = y.size();
  if (y.empty()) return r;
  std::vector<double> c(y.size());
  for (std::size_t i = 0; i < y.size(); ++i) c[i] = y[i] - mu[i];
  r.est_mean = mean(mu);
  r.meas_mean = mean(y);
  r.est_std = stddev(mu);
  r.meas_std = stddev(y);
  r.comp_std = stddev(c);
  r.ratio = r.meas_std > 0.0 ? r.comp_std / r.meas_std : 0.0;
  return r;
}

std::vector<Phase> derive_phases(const RunData& run) {
  if (run.has_phase()) return run.phase;
  const std::size_t n = run.size();
  const std::vector<double>* src = &run.t1_c;
  double threshold = 0.1;  // degC/min
  if (run.has_setpoint()) {
    src = &run.setpoint_c;
    threshold = 0.05;
  } else if (run.has_chamber()) {
    src = &run.chamber_c;
  }
  const std::vector<double> rate = derivative_per_min(*src, 1.0);
  std::vector<Phase> ph(n, Phase::hold);
  for (std::size_t t = 0; t < n; ++t)
    if (rate[t] > threshold) ph[t] = Phase::heating;
    else if (rate[t] < -threshold) ph[t] = Phase::cooling;
  return ph;
}

std::string_view to_string(Verdict v) {
  switch (v) {
    case Verdict::pass: return "pass";
    case Verdict::marginal: return "marginal";
    case Verdict::fail: return "fail";
  }
  return "?";
}

std::expected<void, std::string> VerifyOptions::validate() const {
  if (!(threshold > 0.0 && threshold <= 1.0)) return std::unexpected("threshold must be in (0, 1], got " + std::to_string(threshold));
  if (!(max_noise_factor >= 1.0 && max_noise_factor <= 100.0))
    return std::unexpected("the noise factor must be 1 to 100, got " + std::to_string(max_noise_factor));
  if (!(max_fail_s >= 1.0 && max_fail_s <= 1e6)) return std::unexpected("the longest failing interval must be 1 s to 1e6 s, got " + std::to_string(max_fail_s));
  if (!(k_sigma > 0.0)) return std::unexpected("k_sigma must be positive");
  if (smooth_s < 1 || smooth_s % 2 == 0) return std::unexpected("smooth_s must be a positive odd number of seconds");
  return {};
}

std::expected<Verification, FitError> verify(const Model& m, const RunData& run, double threshold) {
  VerifyOptions o;
  o.threshold = threshold;
  return verify(m, run, o);
}

std::expected<Verification, FitError> verify(const Model& m, const RunData& run, const VerifyOptions& o) {
  if (auto ok = o.validate(); !ok) return fail(FitError::Code::bad_options, "verify: " + ok.error());
  const double threshold = o.threshold;
  auto mu = predict(m, run);
  if (!mu) return std::unexpected(mu.error());
  Verification v;
  v.threshold = threshold;
  const std::size_t n = run.size();
  std::vector<double> w = weights_of(run, &v.n_flagged);
  // Outliers are spikes about the residual's 61 s moving average, not samples of a sustained
  // error: a model that fails for five minutes must show it in Table 1, not lose those samples.
  std::vector<double> res(n, 0.0);
  for (std::size_t t = 0; t < n; ++t)
    if (w[t] != 0.0) res[t] = run.gyro_dph[t] - (*mu)[t];
  const std::vector<double> local = moving_average(res, w, 61);
  std::vector<double> r;
  for (std::size_t t = 0; t < n; ++t)
    if (w[t] != 0.0) r.push_back(res[t] - local[t]);
  const OutlierResult ro = outliers_3sigma(r, 3.0);
  v.n_outliers = ro.removed;
  std::size_t j = 0;
  for (std::size_t t = 0; t < n; ++t)
    if (w[t] != 0.0 && !ro.keep[j++]) w[t] = 0.0;
  const std::vector<Phase> ph = derive_phases(run);
  auto collect = [&](std::optional<Phase> only) {
    std::vector<double> y, p;
    for (std::size_t t = 0; t < n; ++t) {
      if (w[t] == 0.0 || ph[t] == Phase::settle) continue;
      if (only && ph[t] != *only) continue;
      y.push_back(run.gyro_dph[t]);
      p.push_back((*mu)[t]);
    }
    return table1(y, p);
  };
  v.run = collect(std::nullopt);
  if (v.run.n < 2) return fail(FitError::Code::too_short, "no usable samples to verify on");
  for (Phase p : {Phase::hold, Phase::heating, Phase::cooling}) {
    Table1 t = collect(p);
    if (t.n >= 2) v.phases.push_back({p, t});
  }
  v.ratio_pass = v.run.ratio < threshold;
  // The second test: what is left should look like the model's own noise.
  v.noise_test = o.noise_test;
  v.noise_std = ar_process_std(m.ar, m.sigma_a_dph);
  v.noise_factor = v.noise_std > 0.0 ? v.run.comp_std / v.noise_std : std::numeric_limits<double>::infinity();
  {
    // Failing intervals exactly as compare finds them: the residual without its spikes,
    // averaged over smooth_s, beyond k_sigma * sigma_a (settle samples do not count).
    std::vector<double> wf(w);
    std::vector<double> rz(n, 0.0);
    for (std::size_t t = 0; t < n; ++t) {
      if (ph[t] == Phase::settle) wf[t] = 0.0;
      if (wf[t] != 0.0) rz[t] = res[t];
    }
    const std::vector<double> s = moving_average(rz, wf, o.smooth_s);
    const double thr = o.k_sigma * m.sigma_a_dph;
    std::size_t t = 0;
    while (t < n) {
      if (wf[t] == 0.0 || std::abs(s[t]) <= thr) {
        ++t;
        continue;
      }
      const double sign = s[t] > 0 ? 1.0 : -1.0;
      std::size_t e = t;
      while (e < n && sign * s[e] > thr) ++e;
      v.longest_fail_s = std::max(v.longest_fail_s, run.time_s[e - 1] - run.time_s[t] + 1.0);
      t = e;
    }
  }
  auto pct = [](double x) {
    char b[32];
    std::snprintf(b, sizeof b, "%.1f%%", 100.0 * x);
    return std::string(b);
  };
  auto num = [](double x, int d) {
    char b[32];
    std::snprintf(b, sizeof b, "%.*f", d, x);
    return std::string(b);
  };
  if (!v.ratio_pass) v.reasons.push_back("comp/raw " + pct(v.run.ratio) + " is not under " + pct(threshold) + " (the paper's rule)");
  bool second_ok = true;
  if (o.noise_test) {
    if (!(v.noise_factor <= o.max_noise_factor)) {
      second_ok = false;
      v.reasons.push_back("compensated std " + num(v.run.comp_std, 3) + " deg/h is " + num(v.noise_factor, 2) + " x the model's noise std " +
                          num(v.noise_std, 3) + " deg/h (at most " + num(o.max_noise_factor, 2) + " x)");
    }
    if (v.longest_fail_s >= o.max_fail_s) {
      second_ok = false;
      v.reasons.push_back("a failing interval of " + num(v.longest_fail_s, 0) + " s (the residual's " + std::to_string(o.smooth_s) +
                          " s average beyond " + num(o.k_sigma, 1) + " sigma_a; " + num(o.max_fail_s, 0) + " s or more is not passed)");
    }
  }
  v.verdict = !v.ratio_pass ? Verdict::fail : second_ok ? Verdict::pass : Verdict::marginal;
  v.pass = v.verdict == Verdict::pass;
  return v;
}

}  // namespace fogbench::model
