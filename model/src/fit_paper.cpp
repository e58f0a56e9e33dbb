// The paper's two-step method: mu0 and the AR noise from the opening hold, then the trend of
// the smoothed output regressed on the terms with one lag shared by the @auto terms.
#include <algorithm>
#include <cmath>

#include "common.hpp"
#include "fogbench/model/firmware.hpp"
#include "fit_internal.hpp"

namespace fogbench::model::detail {
namespace {

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

}  // namespace

std::expected<PaperPrep, FitError> paper_prep(const RunData& run, const FitOptions& o, const std::vector<double>& w) {
  PaperPrep pp;
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
  pp.mu0_dph = mean(kept);
  for (double& v : kept) v -= pp.mu0_dph;
  const StationarityResult st = stationarity_check(kept);
  auto ar = fit_ar(kept, o.ar_order);
  if (!ar) return fail(FitError::Code::too_short, "opening hold: " + ar.error());
  pp.ar = ar->k;
  pp.sigma_a_dph = std::sqrt(ar->sigma_a2);
  const Whiteness wh = whiteness(ar->residuals, 20, o.ar_order);
  pp.n_hold = hold.size();
  pp.stationary = st.stationary;
  pp.hold_lb_q = wh.lb.q;
  pp.hold_lb_p = wh.lb.p_value;
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
    pp.n_outliers = ro.removed + out.removed;
    if (ro.removed) s = moving_average(run.gyro_dph, ws, o.smooth_s);
  }
  pp.z.resize(n);
  for (std::size_t t = 0; t < n; ++t) pp.z[t] = s[t] - pp.mu0_dph;
  pp.sc = std::make_unique<LagScanner>(n, L, w);
  // The spectrum of w*z, formed as scan() forms it.
  std::vector<double> wz(n);
  for (std::size_t t = 0; t < n; ++t) wz[t] = w[t] * pp.z[t];
  pp.wz_spec = pp.sc->spectrum_of_target(wz);
  return pp;
}

std::expected<Model, FitError> fit_paper(const RunData& run, const std::vector<Term>& terms, const FitOptions& o,
                                         const Evaluated& ev, std::vector<double> w, FitSummary& progress, FitCache* cache) {
  Model m;
  m.method = Method::paper;
  m.shared_lag = true;
  const std::size_t n = run.size();
  const int L = o.max_lag_s;
  progress.stage = "opening hold (step 1)";
  std::expected<PaperPrep, FitError> own;
  const std::expected<PaperPrep, FitError>* prep = nullptr;
  if (cache) {
    prep = &cache->paper_prep(o, w);
  } else {
    own = paper_prep(run, o, w);
    prep = &own;
  }
  if (!*prep) return std::unexpected(prep->error());
  const PaperPrep& pp = **prep;
  m.mu0_dph = pp.mu0_dph;
  m.ar = pp.ar;
  m.sigma_a_dph = pp.sigma_a_dph;
  m.fit.n_hold = pp.n_hold;
  m.fit.stationary = pp.stationary;
  m.fit.ljung_box_q = pp.hold_lb_q;
  m.fit.ljung_box_p = pp.hold_lb_p;
  progress.stage = "trend (step 2)";
  m.fit.n_outliers = pp.n_outliers;
  const std::vector<double>& z = pp.z;
  // Each term extended for its lags (from the cache: with its spectrum, made once per run).
  std::vector<Lagged> own_lagged;
  std::vector<const Lagged*> lagged;
  if (cache) {
    for (std::size_t j = 0; j < terms.size(); ++j) lagged.push_back(&cache->lagged(terms[j], ev.x[j], L, *pp.sc));
  } else {
    own_lagged.reserve(ev.x.size());
    for (const auto& x : ev.x) own_lagged.push_back(detail::make_lagged(x, L));
    for (const auto& l : own_lagged) lagged.push_back(&l);
  }
  std::vector<Column> fixed;
  std::vector<const Lagged*> varying;
  std::vector<std::size_t> fixed_idx, var_idx;
  // With the cache, the scans' sums of each column against z are kept by the columns' keys
  // (PaperPrep::memo): the candidates' refits share the base's terms.
  ScanMemo* memo = cache ? &pp.memo : nullptr;
  auto key_at = [&](std::size_t j, int lag) { return memo ? term_key(terms[j]) + "@" + std::to_string(lag) : std::string(); };
  std::vector<std::string> fixed_keys, var_keys;
  for (std::size_t j = 0; j < terms.size(); ++j) {
    if (terms[j].lag.automatic) {
      varying.push_back(lagged[j]);
      var_idx.push_back(j);
      var_keys.push_back(memo ? term_key(terms[j]) : std::string());
    } else {
      if (terms[j].lag.seconds > L)
        return fail(FitError::Code::bad_options, "term '" + ev.names[j] + "' has lag " + std::to_string(terms[j].lag.seconds) +
                                                     " s, beyond the maximum lag of " + std::to_string(L) + " s");
      fixed.push_back(lagged_view(*lagged[j], L, terms[j].lag.seconds));
      fixed_idx.push_back(j);
      fixed_keys.push_back(key_at(j, terms[j].lag.seconds));
    }
  }
  // With causal_lags, a varying term's lag is max(shared, its causal least): the shared lag is
  // scanned over [Lc, L] (Lc the largest least) with the kernel, and below Lc each shared lag is
  // solved with every term at its own max (a few dozen solves).
  std::vector<int> least(varying.size(), 0);
  int Lc = 0;
  for (std::size_t v = 0; v < var_idx.size(); ++v) {
    if (o.causal_lags) least[v] = std::min(L, firmware::causal_lag_s(*terms[var_idx[v]].expr));
    Lc = std::max(Lc, least[v]);
  }
  auto columns_at = [&](int shared) {
    std::vector<Column> all = fixed;
    for (std::size_t v = 0; v < varying.size(); ++v) all.push_back(lagged_view(*varying[v], L, std::max(shared, least[v])));
    return all;
  };
  ScanResult best = scan(*pp.sc, z, &pp.wz_spec, fixed, varying, Lc, L, memo, fixed_keys, var_keys);
  // Below Lc the shared lags fall into segments [a, b) between the terms' distinct leasts: in
  // each, the terms whose least is above a stay at their least (fixed columns) and the others
  // move with the shared lag, so a segment is one more scan (sums by FFT, not one QR of the
  // whole run per lag: on a 3-day run those QRs were most of diagnose's time). A segment where
  // no term moves is one regression, solved at its first lag.
  {
    std::vector<int> bounds{0, Lc};
    for (int l : least)
      if (l > 0 && l < Lc) bounds.push_back(l);
    std::sort(bounds.begin(), bounds.end());
    bounds.erase(std::unique(bounds.begin(), bounds.end()), bounds.end());
    for (std::size_t s = 0; s + 1 < bounds.size(); ++s) {
      const int a = bounds[s], b = bounds[s + 1];
      std::vector<Column> seg_fixed = fixed;
      std::vector<const Lagged*> seg_varying;
      std::vector<std::string> seg_fixed_keys = fixed_keys, seg_var_keys;
      for (std::size_t v = 0; v < varying.size(); ++v) {
        if (least[v] <= a) {
          seg_varying.push_back(varying[v]);
          seg_var_keys.push_back(var_keys[v]);
        } else {
          seg_fixed.push_back(lagged_view(*varying[v], L, least[v]));
          seg_fixed_keys.push_back(key_at(var_idx[v], least[v]));
        }
      }
      ScanResult r = seg_varying.empty() ? solve_at(z, w, columns_at(a), a)
                                         : scan(*pp.sc, z, &pp.wz_spec, seg_fixed, seg_varying, a, b - 1, memo, seg_fixed_keys, seg_var_keys);
      if (r.ok && (!best.ok || r.sse < best.sse)) best = std::move(r);
    }
  }
  if (!best.ok) return fail(FitError::Code::degenerate, "no lag in 0.." + std::to_string(L) + " s gives a solvable regression");
  // The coefficients at the lag chosen, by the kernel (fixed columns first, as the scan orders them).
  const ScanResult r = solve_at(z, w, columns_at(best.lag), best.lag);
  if (!r.ok) return fail(FitError::Code::degenerate, "the regression is singular at lag " + std::to_string(best.lag) + " s");
  m.terms.resize(terms.size());
  for (std::size_t a = 0; a < fixed_idx.size(); ++a) {
    m.terms[fixed_idx[a]].term = terms[fixed_idx[a]];
    m.terms[fixed_idx[a]].coef = r.theta[a];
  }
  std::string held;
  for (std::size_t v = 0; v < var_idx.size(); ++v) {
    auto& ft = m.terms[var_idx[v]];
    ft.term = terms[var_idx[v]];
    ft.term.lag.seconds = std::max(r.lag, least[v]);
    ft.coef = r.theta[fixed_idx.size() + v];
    if (least[v] > r.lag)
      held += (held.empty() ? "" : ", ") + ev.names[var_idx[v]] + " at " + std::to_string(least[v]) + " s";
  }
  if (!held.empty())
    m.fit.lag_note = "shared lag " + std::to_string(r.lag) + " s; held for a causal firmware form (its slopes' latency): " + held;
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
  finish_stats(m, ev, run.gyro_dph, w, varying.empty() ? 0 : 1, !cache || cache->standard_errors);
  progress.termination = FitTermination::converged;
  progress.why = "two steps, no iteration";
  return m;
}

}  // namespace fogbench::model::detail
