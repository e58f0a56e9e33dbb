// diagnose and add: which effect of the library a model misses, scored by refitting the model
// with each candidate (same method) on the fit run and applying it unchanged to held-out runs.
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <atomic>
#include <map>
#include <memory>
#include <thread>
#include <optional>

#include "fogbench/model/workbench.hpp"
#include "lagscan.hpp"
#include "workbench_internal.hpp"

namespace fogbench::model::workbench {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

std::unexpected<FitError> fail(FitError::Code c, std::string msg) { return std::unexpected(FitError{c, std::move(msg)}); }

std::string with_lag(const std::string& expr, int lag_s) { return lag_s ? expr + "@" + std::to_string(lag_s) : expr; }

// Samples a regression may use: not flagged, finite output.
std::vector<double> good_weights(const RunData& run) {
  std::vector<double> w(run.size(), 1.0);
  for (std::size_t t = 0; t < run.size(); ++t)
    if (run.flagged(t) || !std::isfinite(run.gyro_dph[t])) w[t] = 0.0;
  return w;
}

std::vector<double> lagged(std::span<const double> x, int lag) {
  const std::size_t n = x.size(), l = static_cast<std::size_t>(std::max(0, lag));
  std::vector<double> c(n);
  for (std::size_t t = 0; t < n; ++t) c[t] = x[t >= l ? t - l : 0];
  return c;
}

// The lag scan of a candidate x against the output with the base model's columns B (at their
// fitted lags, intercept included) held in the regression. With u the residual of y on B,
// Frisch-Waugh gives the fall of SSE from adding x(t - i):
//   gain(i) = (x_i' W u)^2 / (x_i' W x_i - x_i' W B (B' W B)^-1 B' W x_i)
// and every sum over t is, for all lags at once, a cross-correlation by FFT (lagscan.hpp).
class CandidateScan {
 public:
  CandidateScan(std::span<const double> y_in, const std::vector<std::vector<double>>& base_cols, std::vector<double> w, int max_lag)
      : sc_(y_in.size(), max_lag, w), w_(std::move(w)), L_(max_lag) {
    const std::size_t n = y_in.size();
    // Samples of weight 0 may hold NaN (a missing gyro reading): 0 * NaN is NaN, so zero them.
    std::vector<double> y(y_in.begin(), y_in.end());
    for (std::size_t t = 0; t < n; ++t)
      if (w_[t] == 0.0) y[t] = 0.0;
    cols_.push_back(std::vector<double>(n, 1.0));
    for (const auto& c : base_cols) cols_.push_back(c);
    const auto k = static_cast<Eigen::Index>(cols_.size());
    Eigen::MatrixXd G(k, k);
    Eigen::VectorXd b(k);
    for (Eigen::Index a = 0; a < k; ++a) {
      double s = 0.0;
      for (std::size_t t = 0; t < n; ++t) s += w_[t] * cols_[a][t] * y[t];
      b(a) = s;
      for (Eigen::Index c = a; c < k; ++c) {
        double g = 0.0;
        for (std::size_t t = 0; t < n; ++t) g += w_[t] * cols_[a][t] * cols_[c][t];
        G(a, c) = G(c, a) = g;
      }
    }
    ldlt_.compute(G);
    ok_ = ldlt_.info() == Eigen::Success && ldlt_.rcond() > 1e-14;
    if (!ok_) return;
    const Eigen::VectorXd th = ldlt_.solve(b);
    u_.assign(y.begin(), y.end());
    for (std::size_t t = 0; t < n; ++t)
      for (Eigen::Index a = 0; a < k; ++a) u_[t] -= th(a) * cols_[a][t];
    std::vector<double> wu(n);
    for (std::size_t t = 0; t < n; ++t) {
      wu[t] = w_[t] * u_[t];
      sse_ += wu[t] * u_[t];
    }
    u_spec_ = sc_.spectrum_of_target(wu);
    for (std::size_t a = 1; a < cols_.size(); ++a) {
      std::vector<double> wc(n);
      for (std::size_t t = 0; t < n; ++t) wc[t] = w_[t] * cols_[a][t];
      col_spec_.push_back(sc_.spectrum_of_target(wc));
    }
  }
  bool ok() const { return ok_; }
  const std::vector<double>& residual() const { return u_; }

  // The lag in [0, max_lag] of largest gain, skipping |lag - avoid| < avoid_half_width.
  std::optional<int> best_lag(std::span<const double> x, std::optional<int> avoid = {}, int avoid_half_width = 0) const {
    auto g = scan(x, avoid, avoid_half_width);
    if (!g) return std::nullopt;
    return g->lag;
  }
  struct Gain {
    int lag = 0;
    double best = 0.0, at_zero = 0.0;  // fall of the weighted SSE, (deg/h)^2
    double sse = 0.0;                  // weighted SSE of the residual before, (deg/h)^2
  };
  std::optional<Gain> scan(std::span<const double> x, std::optional<int> avoid = {}, int avoid_half_width = 0) const {
    if (!ok_) return std::nullopt;
    const detail::Lagged lx = detail::make_lagged(x, L_);
    const std::size_t k = cols_.size();
    std::vector<std::vector<double>> cxb(k);
    cxb[0] = sc_.wsum(lx.ext);
    for (std::size_t a = 1; a < k; ++a) cxb[a] = sc_.corr(lx, col_spec_[a - 1]);
    const std::vector<double> cxu = sc_.corr(lx, u_spec_);
    std::vector<double> sq(lx.ext.size());
    for (std::size_t j = 0; j < sq.size(); ++j) sq[j] = lx.ext[j] * lx.ext[j];
    const std::vector<double> cxx = sc_.wsum(sq);
    std::optional<int> best;
    double best_gain = -1.0, g0 = 0.0;
    Eigen::VectorXd v(static_cast<Eigen::Index>(k));
    for (int i = 0; i <= L_; ++i) {
      if (avoid && std::abs(i - *avoid) < avoid_half_width) continue;
      const auto li = static_cast<std::size_t>(i);
      for (std::size_t a = 0; a < k; ++a) v(static_cast<Eigen::Index>(a)) = cxb[a][li];
      const double den = cxx[li] - v.dot(ldlt_.solve(v));
      // A column (nearly) inside the span of the model's own: nothing new at this lag.
      if (!(den > 1e-9 * std::max(1.0, cxx[li]))) continue;
      const double gain = cxu[li] * cxu[li] / den;
      if (i == 0) g0 = gain;
      if (gain > best_gain) {
        best_gain = gain;
        best = i;
      }
    }
    if (!best) return std::nullopt;
    return Gain{*best, best_gain, g0, sse_};
  }

  // x with the base columns regressed out (for correlations between candidates).
  std::vector<double> partial(std::span<const double> x) const {
    const std::size_t n = x.size(), k = cols_.size();
    Eigen::VectorXd b(static_cast<Eigen::Index>(k));
    for (std::size_t a = 0; a < k; ++a) {
      double s = 0.0;
      for (std::size_t t = 0; t < n; ++t) s += w_[t] * cols_[a][t] * x[t];
      b(static_cast<Eigen::Index>(a)) = s;
    }
    const Eigen::VectorXd th = ldlt_.solve(b);
    std::vector<double> r(x.begin(), x.end());
    for (std::size_t t = 0; t < n; ++t)
      for (std::size_t a = 0; a < k; ++a) r[t] -= th(static_cast<Eigen::Index>(a)) * cols_[a][t];
    return r;
  }

 private:
  detail::LagScanner sc_;
  std::vector<double> w_;
  int L_;
  std::vector<std::vector<double>> cols_;
  Eigen::LDLT<Eigen::MatrixXd> ldlt_;
  bool ok_ = false;
  double sse_ = 0.0;
  std::vector<double> u_;
  detail::Spectrum u_spec_;
  std::vector<detail::Spectrum> col_spec_;
};

double weighted_corr(std::span<const double> a, std::span<const double> b, std::span<const double> w) {
  double sw = 0, ma = 0, mb = 0;
  for (std::size_t t = 0; t < a.size(); ++t) {
    sw += w[t];
    ma += w[t] * a[t];
    mb += w[t] * b[t];
  }
  ma /= sw;
  mb /= sw;
  double sab = 0, saa = 0, sbb = 0;
  for (std::size_t t = 0; t < a.size(); ++t) {
    sab += w[t] * (a[t] - ma) * (b[t] - mb);
    saa += w[t] * (a[t] - ma) * (a[t] - ma);
    sbb += w[t] * (b[t] - mb) * (b[t] - mb);
  }
  return saa > 0 && sbb > 0 ? sab / std::sqrt(saa * sbb) : 0.0;
}

// The candidate's column on a run: the expression evaluated and delayed.
std::expected<std::vector<double>, std::string> column(const Term& t, const RunSignals& s, int lag) {
  auto v = evaluate(*t.expr, s.view());
  if (!v) return std::unexpected(v.error());
  return lagged(*v, lag);
}

// Table 1's compensated std of models on one run, exactly as verify() computes it (flagged
// samples out, 3-sigma outliers of the residual out, settle samples out), with the run's
// signals, phases and unlagged term columns computed once for all the candidates' models.
class Scorer {
 public:
  Scorer(const RunData& run, double tref_c) : run_(run), tref_c_(tref_c), w_(good_weights(run)), phase_(derive_phases(run)) {
    auto s = run_signals(run, tref_c);
    if (s) sig_ = std::move(*s);
    else error_ = s.error().message;
  }
  std::expected<double, std::string> comp_std(const Model& m) {
    if (!error_.empty()) return std::unexpected(error_);
    if (m.tref_c != tref_c_) {  // another reference: no cache (never within one diagnose)
      auto v = verify(m, run_);
      if (!v) return std::unexpected(v.error().message);
      return v->run.comp_std;
    }
    const std::size_t n = run_.size();
    std::vector<double> mu(n, m.mu0_dph);
    for (const auto& ft : m.terms) {
      auto col = column(ft.term);
      if (!col) return std::unexpected(col.error());
      const auto lag = static_cast<std::size_t>(ft.term.lag.seconds);
      const std::vector<double>& x = **col;
      for (std::size_t t = 0; t < n; ++t) mu[t] += ft.coef * x[t >= lag ? t - lag : 0];
    }
    std::vector<double> r;
    r.reserve(n);
    for (std::size_t t = 0; t < n; ++t)
      if (w_[t] != 0.0) r.push_back(run_.gyro_dph[t] - mu[t]);
    const OutlierResult ro = outliers_3sigma(r, 3.0);
    std::vector<double> kept;
    kept.reserve(n);
    std::size_t j = 0;
    for (std::size_t t = 0; t < n; ++t) {
      if (w_[t] == 0.0) continue;
      if (ro.keep[j] && phase_[t] != Phase::settle) kept.push_back(r[j]);
      ++j;
    }
    if (kept.size() < 2) return std::unexpected(run_.name + ": no usable samples to verify on");
    return stddev(kept);
  }

 private:
  std::expected<const std::vector<double>*, std::string> column(const Term& t) {
    const std::string key = to_string(*t.expr);
    auto it = cols_.find(key);
    if (it != cols_.end()) return &it->second;
    auto v = evaluate(*t.expr, sig_.view());
    if (!v) return std::unexpected("term '" + key + "': " + v.error());
    return &cols_.emplace(key, std::move(*v)).first->second;
  }
  const RunData& run_;
  double tref_c_;
  std::vector<double> w_;
  std::vector<Phase> phase_;
  RunSignals sig_;
  std::string error_;
  std::map<std::string, std::vector<double>> cols_;
};

// The model's terms with @auto terms frozen at their fitted lags.
std::vector<Term> frozen_terms(const Model& m) {
  std::vector<Term> out;
  for (const auto& ft : m.terms) {
    Term t = ft.term;
    t.lag.automatic = false;
    out.push_back(t);
  }
  return out;
}

int auto_lag_params(const Model& m) {
  int n = 0;
  for (const auto& ft : m.terms) n += ft.term.lag.automatic;
  return m.method == Method::paper ? std::min(n, 1) : n;  // the paper method shares one lag
}

bool has_key(const Model& m, const std::string& key) {
  for (const auto& ft : m.terms)
    if (term_key(ft.term) == key) return true;
  return false;
}

// The base terms plus one at a fixed lag; when the new term is a model term again, the
// model's lags are frozen (the fit cannot separate the same term at two searched lags).
// Returns the terms and how many lag parameters were estimated outside the fit.
std::pair<TermList, int> extended_terms(const Model& base, const Term& extra, bool lag_scanned) {
  TermList tl;
  const bool repeat = has_key(base, term_key(extra));
  tl.terms = repeat ? frozen_terms(base) : terms_of(base).terms;
  tl.terms.push_back(extra);
  return {tl, (lag_scanned ? 1 : 0) + (repeat ? auto_lag_params(base) : 0)};
}

std::string fmt(double v, int digits) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", digits, v);
  return buf;
}

struct FitRun {
  RunSignals sig;
  std::vector<double> w;
  std::vector<std::vector<double>> base_cols;  // the base model's regressors at fitted lags
};

// The core's fit gives a non-finite gyro sample weight 0 but still multiplies it in (0 * NaN
// is NaN), so a run with a missing reading fails as "singular". A copy with such samples
// flagged missing and set to 0 has the same meaning and fits; runs without any are not copied.
const RunData& finite_gyro(const RunData& run, RunData& copy) {
  bool any = false;
  for (double v : run.gyro_dph) any = any || !std::isfinite(v);
  if (!any) return run;
  copy = run;
  if (copy.flags.empty()) copy.flags.assign(copy.size(), 0);
  for (std::size_t t = 0; t < copy.size(); ++t)
    if (!std::isfinite(copy.gyro_dph[t])) {
      copy.gyro_dph[t] = 0.0;
      copy.flags[t] |= flag::missing;
    }
  return copy;
}

}  // namespace

FitOptions options_of(const Model& m) {
  FitOptions o;
  o.method = m.method;
  o.ar_order = std::max<int>(1, static_cast<int>(m.ar.size()));
  o.max_lag_s = m.max_lag_s;
  o.tref_c = m.tref_c;
  o.smooth_s = m.smooth_s;
  o.hold_s = m.hold_s;
  return o;
}

TermList terms_of(const Model& m) {
  TermList tl;
  for (const auto& ft : m.terms) tl.terms.push_back(ft.term);
  tl.paper = m.method == Method::paper && m.shared_lag && m.terms.size() == 2 && term_key(m.terms[0].term) == "d(T1)" &&
             term_key(m.terms[1].term) == "grad";
  return tl;
}

std::string missing_signal_of(const Expr& e, const RunData& run) {
  if (uses_signal(e, Signal::Ta) && !run.has_chamber())
    return "needs Ta, the chamber air temperature, which " + run.name + " did not record (no chamber_c column)";
  if (uses_signal(e, Signal::ton) && !run.has_power_on())
    return "needs ton, the time since the gyro's power-on, which " + run.name + " did not record (no since_power_on_s column)";
  return {};
}

namespace wbi {
std::expected<Diagnosis, FitError> diagnose_once(const Model& m, const RunData& fit_run_in, std::span<const RunData> held_out,
                                                 const DiagnoseOptions& o, const std::vector<Generated>& gen, SearchStats* stats) {
  RunData fit_copy;
  const RunData& fit_run = finite_gyro(fit_run_in, fit_copy);
  Diagnosis d;
  d.fit_run = fit_run.name;
  for (const auto& h : held_out) d.held_out_runs.push_back(h.name);
  FitOptions fo = options_of(m);
  if (o.max_lag_s) fo.max_lag_s = *o.max_lag_s;
  // The base: the model's terms refitted on the fit run, so that every candidate is compared
  // with the same method on the same data (BIC compares models of one run only).
  auto base = fit(fit_run, terms_of(m), fo);
  if (!base) return std::unexpected(FitError{base.error().code, "fit run " + fit_run.name + ": " + base.error().message});
  d.base_refitted_on_other_run = !m.fitted_on.fingerprint.empty() && m.fitted_on.fingerprint != base->fitted_on.fingerprint;
  d.model_terms = base->terms_string();
  d.method = std::string(to_string(base->method));
  Scorer fit_scorer(fit_run, base->tref_c);
  std::vector<Scorer> held_scorers;
  held_scorers.reserve(held_out.size());
  for (const auto& h : held_out) held_scorers.emplace_back(h, base->tref_c);
  auto rms0 = fit_scorer.comp_std(*base);
  if (!rms0) return fail(FitError::Code::degenerate, "fit run " + fit_run.name + ": " + rms0.error());
  d.rms_fit_dph = *rms0;

  // Coefficients, their standard errors and correlations.
  d.coefs.push_back({"mu0", base->mu0_dph, base->mu0_se, "deg/h"});
  for (const auto& ft : base->terms)
    d.coefs.push_back({with_lag(ft.name(), ft.term.lag.seconds), ft.coef, ft.se, coef_unit(*ft.term.expr)});
  d.coef_corr = base->fit.coef_corr;
  for (std::size_t a = 1; a < d.coef_corr.size(); ++a)
    for (std::size_t b = a + 1; b < d.coef_corr.size(); ++b) {
      const double r = d.coef_corr[a][b];
      if (std::abs(r) <= 0.9) continue;
      const std::string ka = term_key(base->terms[a - 1].term), kb = term_key(base->terms[b - 1].term);
      std::string why = "this run barely tells them apart: only their combination is well determined";
      if ((ka == "d(T1)" && kb == "grad") || (ka == "grad" && kb == "d(T1)"))
        why = "on steady ramps the coil's gradient follows its rate (on a two-node coil grad = -core_tau * dT1/dt "
              "exactly), so the two betas are collinear: a hold right after a fast ramp, where the gradient decays "
              "while the rate is zero, separates them";
      d.collinear_coefs.push_back({d.coefs[a].term, d.coefs[b].term, r, why});
    }

  FitRun fr;
  {
    auto s = run_signals(fit_run, base->tref_c);
    if (!s) return std::unexpected(s.error());
    fr.sig = std::move(*s);
  }
  fr.w = good_weights(fit_run);
  auto bc = regressors(*base, fit_run);
  if (!bc) return std::unexpected(bc.error());
  fr.base_cols = std::move(*bc);

  // Whiteness of the residual prewhitened by the model's AR filter.
  auto mu = predict(*base, fit_run);
  if (!mu) return std::unexpected(mu.error());
  const std::size_t n = fit_run.size();
  std::vector<double> e(n);
  for (std::size_t t = 0; t < n; ++t) e[t] = fr.w[t] != 0.0 ? fit_run.gyro_dph[t] - (*mu)[t] : 0.0;
  // Outliers (3 sigma) would dominate a correlation: they get weight 0 (value 0 in e).
  std::vector<double> wccf = fr.w;
  {
    std::vector<double> r;
    for (std::size_t t = 0; t < n; ++t)
      if (fr.w[t] != 0.0) r.push_back(e[t]);
    const OutlierResult ro = outliers_3sigma(r, 3.0);
    std::size_t j = 0;
    for (std::size_t t = 0; t < n; ++t)
      if (fr.w[t] != 0.0 && !ro.keep[j++]) {
        wccf[t] = 0.0;
        e[t] = 0.0;
      }
  }
  std::vector<double> a = ar_filter(e, base->ar);
  {
    std::vector<double> used;
    for (std::size_t t = base->ar.size(); t < n; ++t)
      if (wccf[t] != 0.0) used.push_back(a[t]);
    d.whiteness = whiteness(used, o.whiteness_lags, static_cast<int>(base->ar.size()));
  }

  // Cross-correlations (MATLAB resid style): residual and regressor both through the
  // model's AR filter; the prewhitened residual is white when the model is adequate, and
  // then the sample CCF of it with any series independent of it lies in +-2/sqrt(N).
  const int Lc = std::max(0, std::min<int>(o.ccf_max_lag_s, static_cast<int>(n) / 2));
  {
    double sw = 0.0, ma = 0.0;
    for (std::size_t t = 0; t < n; ++t) {
      sw += wccf[t];
      ma += wccf[t] * a[t];
    }
    ma /= std::max(1.0, sw);
    std::vector<double> wa(n);
    double saa = 0.0;
    for (std::size_t t = 0; t < n; ++t) {
      wa[t] = wccf[t] * (a[t] - ma);
      saa += wa[t] * (a[t] - ma);
    }
    detail::LagScanner sc(n, Lc, wccf);
    const detail::Spectrum aspec = sc.spectrum_of_target(wa);
    for (const auto& eff : effects_library()) {
      auto t = parse_term(eff.term);
      if (!t) continue;
      auto x = evaluate(*t->expr, fr.sig.view());
      if (!x) continue;
      std::vector<double> xf = ar_filter(*x, base->ar);
      const double mx = std::accumulate(xf.begin(), xf.end(), 0.0) / static_cast<double>(n);
      double sxx = 0.0;
      for (double& v : xf) {
        v -= mx;
        sxx += v * v;
      }
      CrossCorrelation cc;
      cc.term = to_string(*t->expr);
      cc.band = white_band(static_cast<std::size_t>(sw));
      if (!(sxx > 0.0) || !(saa > 0.0)) {
        d.ccf.push_back(cc);
        continue;
      }
      const std::vector<double> c = sc.corr(detail::make_lagged(xf, Lc), aspec);
      cc.r.resize(c.size());
      for (std::size_t i = 0; i < c.size(); ++i) {
        cc.r[i] = c[i] / std::sqrt(saa * sxx);
        if (std::abs(cc.r[i]) > cc.band) ++cc.outside;
        if (std::abs(cc.r[i]) > std::abs(cc.peak_r)) {
          cc.peak_r = cc.r[i];
          cc.peak_lag_s = static_cast<int>(i);
        }
      }
      d.ccf.push_back(std::move(cc));
    }
  }

  // Held-out runs: the base model as fitted, applied unchanged.
  std::vector<std::expected<double, std::string>> held_before;
  for (auto& h : held_scorers) held_before.push_back(h.comp_std(*base));

  // The candidates: the library's terms the model lacks, each model term again at a second
  // lag, and any extra terms asked for.
  struct Cand {
    Term term;
    std::string expr, effect, explanation;
    bool repeat = false;
    bool generated = false;  // from the language search: screened by its lag scan's gain
  };
  std::vector<Cand> cands;
  auto push = [&](const std::string& text, std::string effect, std::string expl, bool repeat) {
    auto t = parse_term(text);
    if (!t) return;
    Cand c{*t, to_string(*t->expr), std::move(effect), std::move(expl), repeat, false};
    c.term.coef = 1.0;
    c.term.coef_given = false;
    for (const auto& x : cands)
      if (x.expr == c.expr && x.repeat == c.repeat) return;
    cands.push_back(std::move(c));
  };
  for (const auto& eff : effects_library()) {
    auto t = parse_term(eff.term);
    if (t && !has_key(*base, to_string(*t->expr))) push(eff.term, eff.name, eff.explanation, false);
  }
  if (o.second_lags)
    for (const auto& ft : base->terms) {
      const std::string k = term_key(ft.term);
      const Effect* eff = find_effect(k);
      push(k, "a second thermal path: " + (eff ? eff->name : k) + " again at another delay",
           "heat reaches the fibre by more than one path (through the flange and through the housing), each with its own delay",
           true);
    }
  for (const auto& x : o.extra_terms) {
    auto t = parse_term(x);
    if (!t) return fail(FitError::Code::bad_term, "extra candidate: " + t.error().pretty());
    const std::string k = to_string(*t->expr);
    if (has_key(*base, k)) continue;
    const Effect* eff = find_effect(k);
    push(x, eff ? eff->name : "user term " + k, eff ? eff->explanation : "", false);
  }

  const std::size_t n_fixed = cands.size();
  for (const auto& g : gen) {
    auto t = parse_term(g.expr);
    if (!t) return fail(FitError::Code::bad_term, "search candidate: " + t.error().pretty());
    const std::string k = to_string(*t->expr);
    if (has_key(*base, k)) continue;
    bool dup = false;
    for (const auto& x : cands) dup = dup || (x.expr == k && !x.repeat);
    if (dup) continue;
    Cand c{*t, k, g.effect, g.explanation, false, true};
    c.term.coef = 1.0;
    c.term.coef_given = false;
    cands.push_back(std::move(c));
  }

  CandidateScan scan(fit_run.gyro_dph, fr.base_cols, fr.w, fo.max_lag_s);
  // The language's candidates are many (docs/workbench.md): each is scanned over its lags (a
  // few FFTs), and only the best by the fall of the squared error, one per group of
  // look-alikes (columns correlating beyond 0.99 with the model's terms regressed out), are
  // refitted and scored like the library's.
  if (cands.size() > n_fixed) {
    struct Screened {
      std::size_t i;
      double gain;
      std::vector<double> partial;
    };
    std::vector<Screened> sc;
    for (std::size_t i = n_fixed; i < cands.size(); ++i) {
      if (!missing_signal_of(*cands[i].term.expr, fit_run).empty()) continue;
      auto x = evaluate(*cands[i].term.expr, fr.sig.view());
      if (!x) continue;
      auto g = scan.scan(*x);
      if (!g) continue;
      sc.push_back({i, g->best, {}});
      auto col = lagged(*x, g->lag);
      sc.back().partial = scan.partial(col);
    }
    if (stats) stats->scanned += sc.size();
    std::sort(sc.begin(), sc.end(), [](const Screened& x1, const Screened& x2) { return x1.gain > x2.gain; });
    std::vector<std::size_t> keep;
    std::vector<const std::vector<double>*> kept_cols;
    for (const auto& x : sc) {
      if (keep.size() >= static_cast<std::size_t>(o.refit_top)) break;
      bool alike = false;
      for (const auto* kc : kept_cols) alike = alike || std::abs(weighted_corr(x.partial, *kc, fr.w)) > 0.99;
      if (alike) continue;
      keep.push_back(x.i);
      kept_cols.push_back(&x.partial);
    }
    std::sort(keep.begin(), keep.end());
    std::vector<Cand> kept(cands.begin(), cands.begin() + static_cast<std::ptrdiff_t>(n_fixed));
    for (std::size_t i : keep) kept.push_back(cands[i]);
    cands = std::move(kept);
  }
  if (stats) stats->refitted += cands.size();
  const double ln_n = std::log(static_cast<double>(std::max<std::size_t>(base->fit.n_used, 2)));
  // Each candidate is independent of the others: evaluated on `threads` threads, each with
  // its own scorers (their column caches are not shared).
  struct Evaluated {
    Candidate c;
    std::vector<double> partial;  // its column with the model's terms regressed out
  };
  auto evaluate_one = [&](std::size_t ci, Scorer& fs, std::vector<Scorer>& held_sc) -> Evaluated {
    const Cand& cd = cands[ci];
    Evaluated out;
    Candidate& c = out.c;
    c.expr = cd.expr;
    c.effect = cd.effect;
    c.explanation = cd.explanation;
    c.unit = coef_unit(*cd.term.expr);
    c.rms_before_dph = d.rms_fit_dph;
    c.second_lag = cd.repeat;
    c.term = cd.expr + (cd.repeat ? "@auto (second lag)" : "@auto");
    if (auto why = missing_signal_of(*cd.term.expr, fit_run); !why.empty()) {
      c.skipped = why + " (the fit run)";
      return out;
    }
    auto x = evaluate(*cd.term.expr, fr.sig.view());
    if (!x) {
      c.skipped = x.error();
      return out;
    }
    std::optional<int> avoid;
    if (cd.repeat)
      for (const auto& ft : base->terms)
        if (term_key(ft.term) == cd.expr) avoid = ft.term.lag.seconds;
    // Within the derivative window (30 s) of the model's own lag the same term is nearly
    // the same column: a second path must be further away to mean anything.
    const auto lag = scan.best_lag(*x, avoid, kDerivativeHalfWidth);
    if (!lag) {
      c.skipped = "no lag in 0.." + std::to_string(fo.max_lag_s) + " s adds anything the model's terms do not already hold";
      return out;
    }
    // The candidate's lag was scanned with the model's terms at the lags they had without
    // it; the refit moves those lags, so scan again with the refitted model's columns until
    // the lag settles (coordinate descent on the lags, as the joint fit does).
    Term t = cd.term;
    t.lag = Lag{false, *lag};
    auto [tl, extra_params] = extended_terms(*base, t, true);
    auto m2 = fit(fit_run, tl, fo);
    std::optional<CandidateScan::Gain> gain = scan.scan(*x, avoid, kDerivativeHalfWidth);
    std::vector<int> lags_before;
    for (const auto& ft : base->terms) lags_before.push_back(ft.term.lag.seconds);
    for (int it = 0; it < o.lag_iterations && m2 && !cd.repeat; ++it) {
      // The model's own lags did not move: the rescan would find the same lag.
      std::vector<int> lags_now;
      for (std::size_t j = 0; j + 1 < m2->terms.size(); ++j) lags_now.push_back(m2->terms[j].term.lag.seconds);
      if (lags_now == lags_before) break;
      lags_before = lags_now;
      auto cols = regressors(*m2, fit_run);
      if (!cols) break;
      cols->pop_back();
      CandidateScan rescan(fit_run.gyro_dph, *cols, fr.w, fo.max_lag_s);
      const auto g2 = rescan.scan(*x);
      if (!g2) break;
      gain = g2;
      if (g2->lag == t.lag.seconds) break;
      Term t2 = t;
      t2.lag.seconds = g2->lag;
      auto [tl2, ep2] = extended_terms(*base, t2, true);
      auto m3 = fit(fit_run, tl2, fo);
      if (!m3 || m3->fit.bic >= m2->fit.bic) break;
      t = t2;
      m2 = std::move(m3);
    }
    // A lag is a parameter: the term without delay costs ln(n) less in BIC, and is the
    // simpler explanation when the runs hardly tell the two apart.
    // Always tried: the scan's gains cannot tell when lag 0 loses, because the refit moves
    // the model's own lags (a T1 hidden at lag 0 scans best at 150 to 450 s beside a paper
    // model whose lag it had pulled to 0).
    const bool try_zero = m2 && t.lag.seconds != 0 && !cd.repeat;
    if (try_zero) {
      Term t0 = t;
      t0.lag.seconds = 0;
      auto [tl0, ep0] = extended_terms(*base, t0, false);
      auto m0 = fit(fit_run, tl0, fo);
      if (m0 && m0->fit.bic + ep0 * ln_n <= m2->fit.bic + extra_params * ln_n) {
        t = t0;
        m2 = std::move(m0);
        extra_params = ep0;
      }
    }
    c.lag_s = t.lag.seconds;
    c.term = with_lag(cd.expr, t.lag.seconds);
    if (!m2) {
      c.skipped = (cd.repeat ? "the same term at a second lag cannot be separated on this run: " : "refit failed: ") + m2.error().message;
      return out;
    }
    c.evaluated = true;
    auto after = fs.comp_std(*m2);
    c.rms_after_dph = after ? *after : kNaN;
    c.fall = c.rms_before_dph > 0.0 ? 1.0 - c.rms_after_dph / c.rms_before_dph : 0.0;
    c.delta_bic = m2->fit.bic + extra_params * ln_n - base->fit.bic;
    const FittedTerm& nt = m2->terms.back();
    c.coef = nt.coef;
    c.se = nt.se;
    c.t = nt.se > 0.0 ? nt.coef / nt.se : 0.0;
    c.p_value = std::erfc(std::abs(c.t) / std::sqrt(2.0));
    double min_fall = std::numeric_limits<double>::infinity();
    int scored = 0;
    for (std::size_t h = 0; h < held_out.size(); ++h) {
      HeldOutScore hs;
      hs.run = held_out[h].name;
      if (!held_before[h]) {
        hs.skipped = "the model does not run on it: " + held_before[h].error();
      } else if (auto why = missing_signal_of(*cd.term.expr, held_out[h]); !why.empty()) {
        hs.skipped = why;
      } else if (auto ha = held_sc[h].comp_std(*m2); !ha) {
        hs.skipped = ha.error();
      } else {
        hs.scored = true;
        hs.rms_before_dph = *held_before[h];
        hs.rms_after_dph = *ha;
        min_fall = std::min(min_fall, hs.rms_before_dph > 0.0 ? 1.0 - hs.rms_after_dph / hs.rms_before_dph : 0.0);
        ++scored;
      }
      c.held_out.push_back(hs);
    }
    c.held_out_fall = scored ? min_fall : 0.0;
    const bool significant = c.p_value < o.max_p_value;
    if (scored > 0) {
      c.detected = c.delta_bic < o.max_delta_bic && significant && c.fall >= o.min_fit_fall && c.held_out_fall >= o.min_held_out_fall;
    } else {
      c.detected = c.delta_bic < o.max_delta_bic_alone && significant && c.fall >= o.min_fit_fall_alone;
    }
    if (c.detected) {
      c.verdict = "missing: compensated std falls " + fmt(100.0 * c.fall, 1) + "% on the fit run" +
                  (scored ? " and at least " + fmt(100.0 * c.held_out_fall, 1) + "% on every held-out run" : "") +
                  ", delta BIC " + fmt(c.delta_bic, 1);
    } else {
      std::string why;
      if (!(c.delta_bic < (scored ? o.max_delta_bic : o.max_delta_bic_alone))) why = "BIC does not fall enough (" + fmt(c.delta_bic, 1) + ")";
      else if (!significant) why = "its coefficient is not significant (p " + fmt(c.p_value, 4) + ")";
      else if (c.fall < (scored ? o.min_fit_fall : o.min_fit_fall_alone)) why = "the fit run's compensated std falls only " + fmt(100.0 * c.fall, 1) + "%";
      else why = "it does not hold up on held-out data (the smallest fall there is " + fmt(100.0 * c.held_out_fall, 1) + "%)";
      c.verdict = "not needed: " + why;
    }
    {
      auto col = column(t, fr.sig, t.lag.seconds);
      if (col) out.partial = scan.partial(*col);
    }
    return out;
  };
  std::vector<Evaluated> results(cands.size());
  {
    unsigned threads = o.threads > 0 ? static_cast<unsigned>(o.threads) : std::max(1u, std::min(4u, std::thread::hardware_concurrency()));
    threads = std::min<unsigned>(threads, static_cast<unsigned>(std::max<std::size_t>(1, cands.size())));
    std::atomic<std::size_t> next{0};
    auto worker = [&](Scorer& fs, std::vector<Scorer>& hs) {
      for (std::size_t ci = next++; ci < cands.size(); ci = next++) results[ci] = evaluate_one(ci, fs, hs);
    };
    std::vector<std::thread> pool;
    std::vector<std::unique_ptr<Scorer>> fit_scorers;
    std::vector<std::vector<Scorer>> held_sets(threads);
    for (unsigned k = 1; k < threads; ++k) {
      fit_scorers.push_back(std::make_unique<Scorer>(fit_run, base->tref_c));
      held_sets[k].reserve(held_out.size());
      for (const auto& h : held_out) held_sets[k].emplace_back(h, base->tref_c);
    }
    for (unsigned k = 1; k < threads; ++k) pool.emplace_back(worker, std::ref(*fit_scorers[k - 1]), std::ref(held_sets[k]));
    worker(fit_scorer, held_scorers);
    for (auto& th : pool) th.join();
  }
  std::vector<std::vector<double>> partial_cols;
  for (auto& r : results) {
    d.candidates.push_back(std::move(r.c));
    partial_cols.push_back(std::move(r.partial));
  }

  // Collinear look-alikes among the detected: their columns, with the model's terms regressed
  // out, correlate so that these profiles cannot tell one from the other.
  for (std::size_t i = 0; i < d.candidates.size(); ++i) {
    auto& ci = d.candidates[i];
    if (!ci.detected || partial_cols[i].empty()) continue;
    for (std::size_t j = 0; j < d.candidates.size(); ++j) {
      const auto& cj = d.candidates[j];
      if (i == j || !cj.detected || partial_cols[j].empty()) continue;
      const double r = weighted_corr(partial_cols[i], partial_cols[j], fr.w);
      if (std::abs(r) < o.collinear_r) continue;
      ci.collinear_with.push_back(cj.term);
      // up(x) + down(x) = x: with x in the model the two are one effect written two ways.
      auto inner = [](const std::string& expr, const char* f) {
        const std::string p = std::string(f) + "(";
        return expr.rfind(p, 0) == 0 && expr.back() == ')' ? expr.substr(p.size(), expr.size() - p.size() - 1) : std::string();
      };
      const std::string xa = inner(ci.expr, "up").empty() ? inner(ci.expr, "down") : inner(ci.expr, "up");
      const std::string xb = inner(cj.expr, "up").empty() ? inner(cj.expr, "down") : inner(cj.expr, "up");
      if (ci.separate_by.empty() && !xa.empty() && xa == xb && ci.expr != cj.expr && has_key(*base, xa)) {
        ci.separate_by = "with " + xa + " in the model, " + ci.expr + " and " + cj.expr + " are the same asymmetry written two ways (up(x) + down(x) = x): no profile separates them and either will do";
      }
      if (ci.separate_by.empty()) {
        const Effect* ea = find_effect(ci.expr);
        const Effect* eb = find_effect(cj.expr);
        const std::string how = ea ? ea->separated_by : eb ? eb->separated_by : "a profile step where the two move differently";
        ci.separate_by = how + " separates " + ci.expr + " from " + cj.expr + " (their columns correlate at r = " + fmt(r, 3) + " here)";
      }
    }
  }

  // Ranking: the detected first, each group by delta BIC, the skipped last.
  std::stable_sort(d.candidates.begin(), d.candidates.end(), [](const Candidate& x, const Candidate& y) {
    auto rank = [](const Candidate& c) { return c.detected ? 0 : c.evaluated ? 1 : 2; };
    if (rank(x) != rank(y)) return rank(x) < rank(y);
    if (rank(x) < 2) return x.delta_bic < y.delta_bic;
    return false;
  });
  // Look-alikes the data cannot rank (BIC within o.tie_bic of the best, columns collinear):
  // the first of them in the library, which lists effects from the most direct (the coil's
  // own temperature) to the most remote (the air, slow paths), is named first.
  if (!d.candidates.empty() && d.candidates.front().detected) {
    auto lib_index = [](const Candidate& c) {
      const auto& lib = effects_library();
      for (std::size_t i = 0; i < lib.size(); ++i)
        if (c.expr == lib[i].term && !c.second_lag) return i;
      return lib.size();
    };
    const Candidate& top = d.candidates.front();
    std::size_t pick = 0;
    for (std::size_t i = 1; i < d.candidates.size(); ++i) {
      const Candidate& c = d.candidates[i];
      if (!c.detected || c.delta_bic - top.delta_bic >= o.tie_bic) continue;
      if (std::find(top.collinear_with.begin(), top.collinear_with.end(), c.term) == top.collinear_with.end()) continue;
      if (lib_index(c) < lib_index(d.candidates[pick])) pick = i;
    }
    if (pick) std::rotate(d.candidates.begin(), d.candidates.begin() + static_cast<std::ptrdiff_t>(pick),
                          d.candidates.begin() + static_cast<std::ptrdiff_t>(pick) + 1);
  }
  d.adequate = d.candidates.empty() || !d.candidates.front().detected;
  d.rule = held_out.empty()
               ? "detected when, refitted with the model: delta BIC < " + fmt(o.max_delta_bic_alone, 0) + ", p < " +
                     fmt(o.max_p_value, 4) + " and the compensated std of the fit run falls by at least " +
                     fmt(100.0 * o.min_fit_fall_alone, 0) + "% (stricter: no held-out run was given)"
               : "detected when, refitted with the model: delta BIC < " + fmt(o.max_delta_bic, 0) + ", p < " +
                     fmt(o.max_p_value, 4) + ", the compensated std of the fit run falls by at least " +
                     fmt(100.0 * o.min_fit_fall, 0) + "% and that of every held-out run by at least " +
                     fmt(100.0 * o.min_held_out_fall, 0) + "% (the refitted model applied unchanged)";
  if (d.adequate) {
    d.summary = "No effect of the library improves the model " + d.model_terms + " on these runs: it is adequate (compensated std " +
                fmt(d.rms_fit_dph, 3) + " deg/h on " + d.fit_run + ").";
  } else {
    const Candidate& b = d.candidates.front();
    d.summary = "Missing effect: " + b.effect + ", term " + b.term + ". Adding it takes the compensated std on " + d.fit_run +
                " from " + fmt(b.rms_before_dph, 3) + " to " + fmt(b.rms_after_dph, 3) + " deg/h";
    for (const auto& h : b.held_out)
      if (h.scored) d.summary += ", on " + h.run + " from " + fmt(h.rms_before_dph, 3) + " to " + fmt(h.rms_after_dph, 3);
    d.summary += ".";
    if (!b.collinear_with.empty()) {
      d.summary += " These profiles cannot tell it from";
      for (std::size_t i = 0; i < b.collinear_with.size(); ++i) d.summary += (i ? ", " : " ") + b.collinear_with[i];
      d.summary += ": " + b.separate_by + ".";
    }
  }
  if (!d.whiteness.white() && d.adequate)
    d.summary += " The residual is not white (Ljung-Box p " + fmt(d.whiteness.lb.p_value, 4) +
                 "): something outside the library, or the noise order, may be missing.";
  return d;
}
}  // namespace wbi

std::expected<AddResult, FitError> add_term(const Model& m, const RunData& run_in, std::string_view text) {
  RunData copy;
  const RunData& run = finite_gyro(run_in, copy);
  auto parsed = parse_term(text);
  if (!parsed) return fail(FitError::Code::bad_term, "--add: " + parsed.error().pretty());
  Term t = *parsed;
  if (t.coef_given) return fail(FitError::Code::bad_term, "--add '" + std::string(text) + "': give the term without a coefficient (the fit estimates it)");
  t.coef = 1.0;
  const std::string key = to_string(*t.expr);
  // The same term again is a second thermal path only at another fixed lag (the model's
  // lags are then frozen at their fitted values: the fit cannot search two lags of one term).
  for (const auto& ft : m.terms)
    if (term_key(ft.term) == key && (t.lag.automatic || ft.term.lag.seconds == t.lag.seconds)) {
      const int other = ft.term.lag.seconds + 120 <= m.max_lag_s ? ft.term.lag.seconds + 120 : std::max(0, ft.term.lag.seconds - 120);
      return fail(FitError::Code::bad_term, "the model already has the term " + key + " (" + m.terms_string() +
                                                "); to add it again as a second thermal path give it a fixed lag other than " +
                                                std::to_string(ft.term.lag.seconds) + " s, e.g. " + key + "@" + std::to_string(other));
    }
  if (auto why = missing_signal_of(*t.expr, run); !why.empty()) return fail(FitError::Code::missing_signal, "term " + key + " " + why);
  const FitOptions fo = options_of(m);
  bool scanned = false;
  // The paper method gives all @auto terms one shared lag: the new term gets its own lag
  // from the scan instead, so that adding it does not move the paper's lag.
  if (t.lag.automatic && fo.method == Method::paper) {
    auto base = fit(run, terms_of(m), fo);
    if (!base) return std::unexpected(FitError{base.error().code, run.name + ": " + base.error().message});
    auto cols = regressors(*base, run);
    if (!cols) return std::unexpected(cols.error());
    auto sig = run_signals(run, fo.tref_c);
    if (!sig) return std::unexpected(sig.error());
    auto x = evaluate(*t.expr, sig->view());
    if (!x) return fail(FitError::Code::missing_signal, "term " + key + ": " + x.error());
    CandidateScan scan(run.gyro_dph, *cols, good_weights(run), fo.max_lag_s);
    const auto lag = scan.best_lag(*x);
    if (!lag) return fail(FitError::Code::collinear, "term " + key + " adds nothing at any lag in 0.." + std::to_string(fo.max_lag_s) +
                                                         " s that the model's terms do not already hold");
    t.lag = Lag{false, *lag};
    scanned = true;
  }
  TermList tl;
  if (has_key(m, key)) {
    tl.terms = frozen_terms(m);
  } else {
    tl = terms_of(m);
    tl.paper = false;
  }
  tl.terms.push_back(t);
  auto m2 = fit(run, tl, fo);
  if (!m2) return std::unexpected(FitError{m2.error().code, run.name + ": " + m2.error().message});
  // A refit that runs the model's own lag to the edge of its scan has not estimated it
  // (lags_at_edge): the model's lags then stay where they were fitted (issue 16: with d(T2)
  // added on the distributed coil, the paper's shared lag ran to 599 s standing in for the
  // absolute term, which the next diagnose then no longer saw).
  std::vector<std::string> kept;
  if (!has_key(m, key) && lags_at_edge(m).empty()) {
    Model own = *m2;
    own.terms.pop_back();
    if (const auto edge = lags_at_edge(own); !edge.empty()) {
      TermList frozen;
      frozen.terms = frozen_terms(m);
      frozen.terms.push_back(t);
      if (auto m3 = fit(run, frozen, fo)) {
        for (const auto& e : edge) kept.push_back("refitted with " + key + ", " + e + "; kept at the lags fitted before (" + m.terms_string() + ")");
        m2 = std::move(m3);
      }
    }
  }
  AddResult r;
  r.notes = kept;
  r.model = std::move(*m2);
  r.model.parent = std::make_shared<const Model>(m);
  const FittedTerm& nt = r.model.terms.back();
  r.added = with_lag(nt.name(), nt.term.lag.seconds);
  r.model.note = "added " + r.added + (scanned ? " (lag from the residual's lag scan)" : "") + " to " + m.terms_string() +
                 ", refitted on " + run.name + " (" + std::string(to_string(fo.method)) + " method)";
  for (const auto& k : kept) r.model.note += "; " + k;
  return r;
}

}  // namespace fogbench::model::workbench
