// The joint method: regression with AR errors by Cochrane-Orcutt. OLS first, then AR(p) of
// the residual, prewhiten, refit the coefficients and the @auto lags (each its own, by
// coordinate descent), until the coefficients, AR and lags settle.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <optional>

#include "common.hpp"
#include "fogbench/model/firmware.hpp"
#include "fit_internal.hpp"

namespace fogbench::model::detail {
namespace {

// The joint fit's regression at one whitening: y on [c, x_j(t - lag_j)], the @auto lags
// chosen by coordinate descent. It owns what it finds (lags, coefficients, RSS); the fit
// reads them back after each solve.
class JointSolver {
 public:
  // lags: the fixed terms' lags (the @auto ones start anywhere: the first search sets them).
  // least: per term, the least lag an @auto search may take (s; FitOptions::causal_lags).
  JointSolver(const std::vector<Term>& terms, const std::vector<std::string>& names, int max_lag_s, std::vector<int> lags,
              std::vector<int> least)
      : terms_(terms), names_(names), max_lag_s_(max_lag_s), lag_(std::move(lags)), least_(std::move(least)),
        theta_(terms.size() + 1, 0.0), twins_(terms.size()) {
    for (const auto& t : terms_) n_auto_ += t.lag.automatic;
    for (std::size_t a = 0; a < terms_.size(); ++a)
      for (std::size_t b = 0; b < terms_.size(); ++b)
        if (a != b && term_key(terms_[a]) == term_key(terms_[b])) twins_[a].push_back(b);
  }

  // One solve of yf on [c, xf_j(t - lag_j)], yf and xf the (prewhitened) series, c the
  // intercept's column (1 - sum k). With move_lags, the @auto lags are searched first: on the
  // first call one lag shared by all (one scan), then up to max_sweeps sweeps refining each in
  // turn. Returns whether any lag moved in the sweeps.
  std::expected<bool, FitError> solve(const LagScanner& sc, std::span<const double> yf, const std::vector<Lagged>& xf,
                                      double c, bool move_lags, int max_sweeps = 6) {
    const std::size_t n = sc.n(), nt = terms_.size();
    const int L = max_lag_s_;
    Spectrum& wy_spec = wy_spec_;
    wy_spec.clear();
    if (move_lags && n_auto_ > 0) {
      std::vector<double>& wy = wy_;
      wy.resize(n);
      for (std::size_t t = 0; t < n; ++t) wy[t] = sc.weights()[t] * yf[t];
      sc.spectrum_of_target(wy, wy_spec);
      if (first_pass_) {
        // One lag shared by the @auto terms; a term's second copy (a second thermal path)
        // would be the same column at that lag, so it waits for the shared scan and then
        // takes the best lag away from its twins'.
        std::vector<Column> fixed{{nullptr, c}};
        std::vector<const Lagged*> var;
        std::vector<std::size_t> later;
        for (std::size_t l = 0; l < nt; ++l) {
          if (!terms_[l].lag.automatic) fixed.push_back(lagged_view(xf[l], L, lag_[l]));
          else if (first_auto_of_key(l)) var.push_back(&xf[l]);
          else later.push_back(l);
        }
        const ScanResult r = scan(sc, yf, &wy_spec, fixed, var, 0, L);
        if (r.ok)
          for (std::size_t l = 0; l < nt; ++l)
            if (terms_[l].lag.automatic && first_auto_of_key(l)) lag_[l] = std::max(r.lag, least_[l]);
        // The shared lag of two paths is often a blend of both, from where coordinate descent
        // does not find them (38 s and 300 s started at 102 s and 520 s): the first copy's lag
        // is searched too, on a grid of kTwinGrid_s, the copy's best lag found for each.
        std::vector<bool> placed(nt, true);
        for (std::size_t l : later) placed[l] = false;
        for (std::size_t j : later) {
          std::size_t first = j;
          for (std::size_t t : twins_[j])
            if (t < first) first = t;
          ScanResult best;
          int best_first = lag_[first];
          std::vector<int> lags = lag_;
          for (int g = least_[first]; g <= L; g += kTwinGrid_s) {
            lags[first] = g;
            std::vector<Column> others{{nullptr, c}};
            for (std::size_t l = 0; l < nt; ++l)
              if (l != j && placed[l]) others.push_back(lagged_view(xf[l], L, lags[l]));
            ScanResult rj = scan_apart(sc, yf, &wy_spec, others, xf[j], j, lags, placed);
            if (rj.ok && (!best.ok || rj.sse < best.sse)) {
              best = std::move(rj);
              best_first = g;
            }
          }
          if (best.ok) {
            lag_[first] = best_first;
            lag_[j] = best.lag;
          }
          placed[j] = true;
        }
        first_pass_ = false;
      }
    }
    bool moved = false;
    for (int sweep = 0; sweep < max_sweeps && move_lags; ++sweep) {
      bool moved_now = false;
      for (std::size_t j = 0; j < nt; ++j) {
        if (!terms_[j].lag.automatic) continue;
        std::vector<Column>& fixed = columns_;
        fixed.assign(1, Column{nullptr, c});
        for (std::size_t l = 0; l < nt; ++l)
          if (l != j) fixed.push_back(lagged_view(xf[l], L, lag_[l]));
        all_placed_.assign(nt, true);
        const ScanResult r = scan_apart(sc, yf, &wy_spec, fixed, xf[j], j, lag_, all_placed_);
        if (!r.ok) return fail(FitError::Code::degenerate, "term '" + names_[j] + "': no lag gives a solvable regression");
        if (r.lag != lag_[j]) moved_now = moved = true;
        lag_[j] = r.lag;
      }
      if (!moved_now) break;
    }
    std::vector<Column>& all = columns_;
    all.assign(1, Column{nullptr, c});
    for (std::size_t l = 0; l < nt; ++l) all.push_back(lagged_view(xf[l], L, lag_[l]));
    const ScanResult r = solve_at(yf, sc.weights(), all);
    if (!r.ok) return fail(FitError::Code::degenerate, "the regression is singular at the chosen lags");
    theta_.assign(r.theta.begin(), r.theta.end());
    rss_ = r.sse;
    return moved;
  }

  // e(t) = y(t) - theta_0 - sum_j theta_j x_j(t - lag_j), the unlagged terms x read in place.
  void residual(std::span<const double> y, const std::vector<std::span<const double>>& x, std::vector<double>& e) const {
    const std::size_t n = y.size(), nt = terms_.size();
    e.assign(y.begin(), y.end());
    for (std::size_t t = 0; t < n; ++t) {
      e[t] -= theta_[0];
      for (std::size_t j = 0; j < nt; ++j) {
        const auto lj = static_cast<std::size_t>(lag_[j]);
        e[t] -= theta_[j + 1] * x[j][t >= lj ? t - lj : 0];
      }
    }
  }

  const std::vector<double>& theta() const { return theta_; }  // [mu0 (the intercept), beta_1..m]
  const std::vector<int>& lags() const { return lag_; }         // s, per term

  // Two copies of one term within the derivative window of each other (30 s) are nearly the
  // same column: a second path must be further away to mean anything (the workbench's rule).
  static constexpr int kTwinApart_s = kDerivativeHalfWidth;
  // s, the grid of the first copy's lag in the start of a second path's search.
  static constexpr int kTwinGrid_s = 10;
  double rss() const { return rss_; }                          // of the last solve, (deg/h)^2
  int n_auto() const { return n_auto_; }

 private:
  const std::vector<Term>& terms_;
  const std::vector<std::string>& names_;
  // The first @auto copy of its term (or the only one).
  bool first_auto_of_key(std::size_t l) const {
    for (std::size_t t : twins_[l])
      if (t < l && terms_[t].lag.automatic) return false;
    return true;
  }

  // scan() of term j over 0..max_lag, away from the lags (s, per term) of its twins that are
  // placed: the allowed stretches scanned one by one, the least SSE kept.
  ScanResult scan_apart(const LagScanner& sc, std::span<const double> yf, const Spectrum* wy_spec,
                        const std::vector<Column>& fixed, const Lagged& x, std::size_t j,
                        const std::vector<int>& lags, const std::vector<bool>& placed) const {
    const int L = max_lag_s_;
    std::vector<std::pair<int, int>> banned;
    for (std::size_t t : twins_[j])
      if (placed[t]) banned.emplace_back(lags[t] - kTwinApart_s, lags[t] + kTwinApart_s);
    std::sort(banned.begin(), banned.end());
    ScanResult best;
    int lo = least_[j];
    auto try_range = [&](int a, int b) {
      if (a > b) return;
      ScanResult r = scan(sc, yf, wy_spec, fixed, {&x}, a, b);
      if (r.ok && (!best.ok || r.sse < best.sse)) best = std::move(r);
    };
    for (const auto& [a, b] : banned) {
      try_range(lo, std::min(a - 1, L));
      lo = std::max(lo, b + 1);
    }
    try_range(lo, L);
    return best;
  }

  int max_lag_s_;
  int n_auto_ = 0;
  std::vector<int> lag_;
  std::vector<int> least_;
  std::vector<double> theta_;
  double rss_ = 0.0;
  bool first_pass_ = true;
  std::vector<std::vector<std::size_t>> twins_;  // per term, the other terms of the same key
  // solve()'s work space, kept between the fit's iterations (no allocation once sized).
  std::vector<double> wy_;
  Spectrum wy_spec_;
  std::vector<Column> columns_;
  std::vector<bool> all_placed_;
};

}  // namespace

std::expected<Model, FitError> fit_joint(const RunData& run, const std::vector<Term>& terms, const FitOptions& o,
                                         const Evaluated& ev, std::vector<double> w, FitSummary& progress) {
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
  std::vector<int> fixed_lag(nt);
  for (std::size_t j = 0; j < nt; ++j) {
    fixed_lag[j] = terms[j].lag.automatic ? 0 : terms[j].lag.seconds;
    if (fixed_lag[j] > L)
      return fail(FitError::Code::bad_options, "term '" + ev.names[j] + "' has lag " + std::to_string(fixed_lag[j]) +
                                                   " s, beyond the maximum lag of " + std::to_string(L) + " s");
  }
  std::vector<int> least(nt, 0);
  for (std::size_t j = 0; j < nt; ++j)
    if (o.causal_lags && terms[j].lag.automatic) least[j] = std::min(L, firmware::causal_lag_s(*terms[j].expr));
  JointSolver solver(terms, ev.names, L, fixed_lag, least);
  const int n_auto = solver.n_auto();
  std::vector<double> k(static_cast<std::size_t>(p), 0.0);

  // Ordinary least squares first (white errors), then the outliers of its residual.
  std::vector<Lagged> xl;
  for (const auto& x : ev.x) xl.push_back(make_lagged(x, L));
  progress.stage = "ordinary least squares (white errors)";
  {
    // Only the shared-lag start here: the lags are refined once the noise is whitened.
    LagScanner sc(n, L, w);
    auto r = solver.solve(sc, y, xl, 1.0, true, /*max_sweeps=*/0);
    if (!r) return std::unexpected(r.error());
    m.fit.rss = solver.rss();
  }
  std::vector<double> e;
  solver.residual(y, ev.x, e);
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
  double change = 0.0;
  bool lags_moved = false;
  // The iterations' buffers, sized on the first and reused (issue 30: bench_fit_alloc counts
  // each iteration's allocations): the prewhitened target and terms, the scanner, the whitened
  // residual, the previous estimates.
  std::vector<double> yf, innov, old;
  std::vector<Lagged> xf(xl.size());
  std::vector<int> old_lag;
  std::optional<LagScanner> sc;
  char stage[48];
  for (; it < o.max_iterations && !converged; ++it) {
    progress.iterations = it + 1;
    std::snprintf(stage, sizeof stage, "Cochrane-Orcutt iteration %d", it + 1);
    progress.stage.assign(stage);
    auto ar = fit_ar_rows(e, w, p);
    if (!ar) return fail(FitError::Code::too_short, "joint fit: " + ar.error());
    const std::vector<double>& k_new = ar->k;
    double ksum = 0.0;
    for (double v : k_new) ksum += v;
    for (std::size_t t = 0; t < n; ++t) {
      bool ok = t >= static_cast<std::size_t>(p);
      for (int j = 0; j <= p && ok; ++j) ok = w[t - static_cast<std::size_t>(j)] != 0.0;
      wf[t] = ok ? 1.0 : 0.0;
    }
    ar_filter(y, k_new, yf);
    for (std::size_t j = 0; j < xl.size(); ++j) {
      ar_filter(xl[j].ext, k_new, xf[j].ext);
      xf[j].spec.clear();  // made again from the new ext on first use, in the same buffer
    }
    old.assign(solver.theta().begin(), solver.theta().end());
    old_lag.assign(solver.lags().begin(), solver.lags().end());
    if (sc) sc->set_weights(wf);
    else sc.emplace(n, L, wf);
    // Lags move little once the noise is whitened: search them on the first iteration and
    // whenever the coefficients have settled (to confirm), not on every iteration.
    auto r = solver.solve(*sc, yf, xf, 1.0 - ksum, search_lags);
    if (!r) return std::unexpected(r.error());
    m.fit.rss = solver.rss();
    const std::vector<double>& theta = solver.theta();
    // The intercept of the prewhitened regression is mu0 itself (its column is 1 - sum k).
    change = 0.0;
    for (std::size_t j = 0; j <= nt; ++j) change = std::max(change, std::abs(theta[j] - old[j]) / std::max(1e-6, std::abs(theta[j])));
    for (std::size_t j = 0; j < k.size(); ++j) change = std::max(change, std::abs(k_new[j] - k[j]));
    // Confirm the lags once the coefficients have settled, unless the whitening has barely
    // changed since they were searched (AR coefficients within 0.01: the lag sums differ by
    // less than the noise).
    double k_drift = 0.0;
    for (std::size_t j = 0; j < k_new.size(); ++j) k_drift = std::max(k_drift, std::abs(k_new[j] - k_at_search[j]));
    if (search_lags) k_at_search.assign(k_new.begin(), k_new.end());
    k.assign(k_new.begin(), k_new.end());
    lags_moved = solver.lags() != old_lag;
    const bool settled = change < o.tolerance && !lags_moved;
    converged = settled && (search_lags || n_auto == 0 || k_drift < 0.01);
    search_lags = settled && !converged;
    solver.residual(y, ev.x, e);
    double rss = 0.0, cnt = 0.0;
    ar_filter(e, k, innov);
    for (std::size_t t = 0; t < n; ++t)
      if (wf[t] != 0.0) {
        rss += innov[t] * innov[t];
        cnt += 1.0;
      }
    m.sigma_a_dph = std::sqrt(rss / std::max(1.0, cnt));
    m.fit.n_used = static_cast<std::size_t>(cnt);
  }
  progress.last_change = change;
  if (converged) {
    progress.termination = FitTermination::converged;
    progress.why = "coefficients and AR settled within the tolerance " + std::to_string(o.tolerance) + " at the chosen lags";
  } else {
    progress.termination = FitTermination::no_convergence;
    progress.why = "max_iterations (" + std::to_string(o.max_iterations) + ") reached with " +
                   (lags_moved              ? std::string("the lags still moving")
                    : change >= o.tolerance ? "the coefficients still changing by " + std::to_string(change) +
                                                  " (relative; tolerance " + std::to_string(o.tolerance) + ")"
                                            : std::string("the coefficients settled but the lags not yet confirmed")) +
                   ": the model holds the last iteration's estimates";
  }
  m.fit.iterations = it;
  m.fit.converged = converged;
  m.ar = k;
  m.mu0_dph = solver.theta()[0];
  m.terms.resize(nt);
  for (std::size_t j = 0; j < nt; ++j) {
    m.terms[j].term = terms[j];
    m.terms[j].term.lag.seconds = solver.lags()[j];
    m.terms[j].coef = solver.theta()[j + 1];
  }
  {
    std::string held;
    for (std::size_t j = 0; j < nt; ++j)
      if (least[j] > 0 && solver.lags()[j] == least[j])
        held += (held.empty() ? "" : ", ") + ev.names[j] + " at " + std::to_string(least[j]) + " s";
    if (!held.empty()) m.fit.lag_note = "held at the least lag of a causal firmware form (its slopes' latency): " + held;
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

}  // namespace fogbench::model::detail
