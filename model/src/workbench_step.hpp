// Internal to model/: the pieces of diagnose's step (workbench_diagnose.cpp: the stages of
// diagnose_once and add_term; workbench_candidate.cpp: one candidate's lag, refit and score):
// the lag scan beside a model, the scorer, the candidate list's entries.
#pragma once

#include <Eigen/Dense>
#include <algorithm>
#include <cassert>
#include <cmath>
#include <expected>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "common.hpp"
#include "fit_internal.hpp"
#include "fogbench/model/workbench.hpp"
#include "lagscan.hpp"
#include "workbench_internal.hpp"

namespace fogbench::model::workbench::wbi {

inline std::string with_lag(const std::string& expr, int lag_s) { return lag_s ? expr + "@" + std::to_string(lag_s) : expr; }

// x delayed by lag samples, its first value standing in before the start.
inline std::vector<double> lagged(std::span<const double> x, int lag) {
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
  // A base column: x delayed by lag samples (its first value before the start), read where it
  // lies (a run's fit cache's column, pinned for the calling thread while the scan is made) or
  // held in own (x then views it). Moved, never copied (x would point into the original's own).
  struct BaseColumn {
    std::vector<double> own;
    std::span<const double> x;
    std::size_t lag = 0;
    explicit BaseColumn(std::vector<double> v) : own(std::move(v)), x(own) {}
    BaseColumn(std::span<const double> view, std::size_t lag_samples) : x(view), lag(lag_samples) {}
    BaseColumn(BaseColumn&&) = default;
    BaseColumn& operator=(BaseColumn&&) = default;
    BaseColumn(const BaseColumn&) = delete;
    BaseColumn& operator=(const BaseColumn&) = delete;
    double at(std::size_t t) const { return x[t >= lag ? t - lag : 0]; }
  };
  static std::vector<BaseColumn> owned(std::vector<std::vector<double>> cols) {
    std::vector<BaseColumn> out;
    out.reserve(cols.size());
    for (auto& c : cols) out.emplace_back(std::move(c));
    return out;
  }
  // keys and spectra (both or neither): each base column's key (its term's key at its lag) and
  // the run's cache of the weighted columns' spectra (FitCache::spectrum; w must be the run's
  // good_weights), so that the rescans beside models at the same lags transform them once.
  // base_cols are taken by value (a caller done with its columns moves them in, one run-length
  // copy fewer each) and kept only for partial(): with keep_columns false they are dropped once
  // their sums and spectra are made (a rescan's: 6.3 MB on the 3-day run, one per thread).
  CandidateScan(std::span<const double> y_in, std::vector<std::vector<double>> base_cols, std::vector<double> w, int max_lag,
                std::span<const std::string> keys = {}, detail::FitCache* spectra = nullptr, bool keep_columns = true)
      : CandidateScan(y_in, owned(std::move(base_cols)), std::move(w), max_lag, keys, spectra, keep_columns) {}
  // The same with the base columns as views (BaseColumn: a rescan's, read in its run's fit cache
  // rather than copied at their lags; the same values, the same sums).
  CandidateScan(std::span<const double> y_in, std::vector<BaseColumn> base_cols, std::vector<double> w, int max_lag,
                std::span<const std::string> keys = {}, detail::FitCache* spectra = nullptr, bool keep_columns = true)
      : sc_(y_in.size(), max_lag, std::move(w)), L_(max_lag) {
    const std::vector<double>& wv = sc_.weights();  // the weights are the scanner's (one copy)
    const std::size_t n = y_in.size();
    const std::size_t n_base = base_cols.size();
    // Samples of weight 0 may hold NaN (a missing gyro reading): 0 * NaN is NaN, so zero them.
    std::vector<double> y(y_in.begin(), y_in.end());
    for (std::size_t t = 0; t < n; ++t)
      if (wv[t] == 0.0) y[t] = 0.0;
    cols_ = std::move(base_cols);
    const auto k = static_cast<Eigen::Index>(cols_.size() + 1);
    Eigen::MatrixXd G(k, k);
    Eigen::VectorXd b(k);
    for (Eigen::Index a = 0; a < k; ++a) {
      double s = 0.0;
      for (std::size_t t = 0; t < n; ++t) s += wv[t] * col(static_cast<std::size_t>(a), t) * y[t];
      b(a) = s;
      for (Eigen::Index c = a; c < k; ++c) {
        double g = 0.0;
        for (std::size_t t = 0; t < n; ++t) g += wv[t] * col(static_cast<std::size_t>(a), t) * col(static_cast<std::size_t>(c), t);
        G(a, c) = G(c, a) = g;
      }
    }
    ldlt_.compute(G);
    ok_ = ldlt_.info() == Eigen::Success && ldlt_.rcond() > 1e-14;
    if (!ok_) return;
    const Eigen::VectorXd th = ldlt_.solve(b);
    // The residual u = y - B theta, in y's place, then w * u in the same place (sse takes each
    // u before it is weighted): only its spectrum is kept.
    std::vector<double>& u = y;
    for (std::size_t t = 0; t < n; ++t)
      for (Eigen::Index a = 0; a < k; ++a) u[t] -= th(a) * col(static_cast<std::size_t>(a), t);
    for (std::size_t t = 0; t < n; ++t) {
      const double ut = u[t];
      u[t] = wv[t] * ut;
      sse_ += u[t] * ut;
    }
    u_spec_ = sc_.spectrum_of_target(u);
    for (std::size_t a = 1; a <= cols_.size(); ++a) {
      auto make = [&] {
        // w * the column at its lag, made block by block as it is transformed (no array of it).
        detail::Spectrum s;
        sc_.spectrum_of_lagged_product(wv, cols_[a - 1].x, cols_[a - 1].lag, s);
        return s;
      };
      if (spectra && keys.size() == n_base)
        col_spec_.push_back(spectra->spectrum(keys[a - 1] + "/L" + std::to_string(L_), make));
      else
        col_spec_.push_back(std::make_shared<const detail::Spectrum>(make()));
    }
    if (!keep_columns) {
      kept_ = false;
      std::vector<BaseColumn>().swap(cols_);
    }
  }
  bool ok() const { return ok_; }

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
  // A candidate's column prepared for its scans on this run: its lag extension with the spectrum
  // of its blocks (made on the first scan) and its weighted sums, which depend on the column,
  // the run's weights and the lag range only. Made once for a candidate and handed to each of
  // its scans (the rescans beside the refitted model's columns: other scans of the same run),
  // it gives the numbers scan(x) computes. The scan that made it must outlive it.
  struct Prepared {
    detail::Lagged lx;
    std::vector<double> s1, sxx;           // sum_t w(t) x(t - i) and sum_t w(t) x(t - i)^2, i = 0..L
    const std::vector<double>* w = nullptr;  // the weights of s1 and sxx (the preparing scan's)
    int max_lag = 0;                         // L, s; lx.ext is L copies of x(0), then x
  };
  Prepared prepare(std::span<const double> x) const {
    Prepared p;
    p.lx = detail::make_lagged(x, L_);
    p.s1 = sc_.wsum(p.lx.ext);
    sc_.wsum_product(p.lx.ext, p.lx.ext, p.sxx);  // x(t - i)^2, no array of the squares
    p.w = &sc_.weights();
    p.max_lag = L_;
    return p;
  }
  std::optional<Gain> scan(std::span<const double> x, std::optional<int> avoid = {}, int avoid_half_width = 0) const {
    if (!ok_) return std::nullopt;
    return scan(prepare(x), avoid, avoid_half_width);
  }
  // The same scan of a prepared column (prepare(): this scan's, or another's on the same run;
  // with other weights or lags its sums are made again here).
  std::optional<Gain> scan(const Prepared& px, std::optional<int> avoid = {}, int avoid_half_width = 0) const {
    if (!ok_) return std::nullopt;
    const bool same = px.max_lag == L_ && px.lx.ext.size() == sc_.weights().size() + static_cast<std::size_t>(L_) && px.w != nullptr &&
                      (px.w == &sc_.weights() || *px.w == sc_.weights());
    if (!same) return scan(std::span<const double>(px.lx.ext).subspan(static_cast<std::size_t>(px.max_lag)), avoid, avoid_half_width);
    const detail::Lagged& lx = px.lx;
    const std::size_t k = col_spec_.size() + 1;  // the base columns (their spectra: the columns may be dropped)
    std::vector<std::vector<double>> cxb(k);
    cxb[0] = px.s1;
    for (std::size_t a = 1; a < k; ++a) cxb[a] = sc_.corr(lx, *col_spec_[a - 1]);
    const std::vector<double> cxu = sc_.corr(lx, u_spec_);
    const std::vector<double>& cxx = px.sxx;
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
  // Only on a scan that kept its columns (keep_columns).
  std::vector<double> partial(std::span<const double> x) const {
    assert(kept_);
    const std::size_t n = x.size(), k = cols_.size() + 1;
    const std::vector<double>& wts = sc_.weights();
    Eigen::VectorXd b(static_cast<Eigen::Index>(k));
    for (std::size_t a = 0; a < k; ++a) {
      double s = 0.0;
      for (std::size_t t = 0; t < n; ++t) s += wts[t] * col(a, t) * x[t];
      b(static_cast<Eigen::Index>(a)) = s;
    }
    const Eigen::VectorXd th = ldlt_.solve(b);
    std::vector<double> r(x.begin(), x.end());
    for (std::size_t t = 0; t < n; ++t)
      for (std::size_t a = 0; a < k; ++a) r[t] -= th(static_cast<Eigen::Index>(a)) * col(a, t);
    return r;
  }

 private:
  detail::LagScanner sc_;
  int L_;
  // The base columns; column 0 of the regression is the intercept's, 1 everywhere, not stored
  // (col(0, t) is 1.0: w * 1.0 * y is w * y exactly, the same sums as a stored column of ones).
  std::vector<BaseColumn> cols_;
  bool kept_ = true;  // cols_ kept for partial()
  double col(std::size_t a, std::size_t t) const { return a == 0 ? 1.0 : cols_[a - 1].at(t); }
  Eigen::LDLT<Eigen::MatrixXd> ldlt_;
  bool ok_ = false;
  double sse_ = 0.0;
  detail::Spectrum u_spec_;  // the weighted residual's (the residual itself is not kept)
  std::vector<std::shared_ptr<const detail::Spectrum>> col_spec_;
};


// The lag scan beside a model on a run: the model's regressors at their fitted lags (all, or
// all but the last term: the candidate just added) held in the regression, the run's good
// samples weighted. The one place diagnose's rescan and add_term build it.
std::expected<CandidateScan, FitError> scan_beside(const Model& m, const RunData& run, int max_lag_s, bool without_last_term = false);
// The same with the model's columns from the run's fit cache (cache.run() is run).
std::expected<CandidateScan, FitError> scan_beside(const Model& m, detail::FitCache& cache, int max_lag_s, bool without_last_term);

// The candidate's column on a run: the expression evaluated and delayed.
inline std::expected<std::vector<double>, std::string> column(const Term& t, const RunSignals& s, int lag) {
  auto v = evaluate(*t.expr, s.view());
  if (!v) return std::unexpected(v.error());
  return lagged(*v, lag);
}

// Table 1's compensated std of models on one run, exactly as verify() computes it (flagged
// samples out, 3-sigma outliers of the residual out, settle samples out), with the run's
// signals, phases and unlagged term columns computed once for all the candidates' models.
// What does not change (the run's signals, weights and phases) is held once and shared by the
// scorers of the same run (sibling(): one per thread), read only.
class Scorer {
 public:
  // sig: the run's signals at tref_c when the caller has them (run_signals(run, tref_c): the
  // same numbers), shared instead of computed again.
  Scorer(const RunData& run, double tref_c, std::shared_ptr<const RunSignals> sig = nullptr)
      : run_(run), tref_c_(tref_c), fixed_(make_fixed(run, tref_c, std::move(sig))) {}
  // A scorer of the same run for another thread: the run's signals, weights and phases shared
  // (read only), its own column cache, no fit cache.
  Scorer sibling() const { return Scorer(Share{}, run_, tref_c_, fixed_); }
  // The run's signals (null when they could not be made: comp_std says why).
  const std::shared_ptr<const RunSignals>& signals() const { return fixed_->sig; }

  std::expected<double, std::string> comp_std(const Model& m) {
    if (!fixed_->error.empty()) return std::unexpected(fixed_->error);
    if (m.tref_c != tref_c_) {  // another reference: no cache (never within one diagnose)
      auto v = verify(m, run_);
      if (!v) return std::unexpected(v.error().message);
      return v->run.comp_std;
    }
    const std::vector<double>& w = fixed_->w;
    const std::vector<Phase>& phase = fixed_->phase;
    const std::size_t n = run_.size();
    std::vector<double> mu(n, m.mu0_dph);
    for (const auto& ft : m.terms) {
      auto col = column(ft.term);
      if (!col) return std::unexpected(col.error());
      const auto lag = static_cast<std::size_t>(ft.term.lag.seconds);
      const std::span<const double> x = *col;
      for (std::size_t t = 0; t < n; ++t) mu[t] += ft.coef * x[t >= lag ? t - lag : 0];
    }
    std::vector<double> r;
    r.reserve(n);
    for (std::size_t t = 0; t < n; ++t)
      if (w[t] != 0.0) r.push_back(run_.gyro_dph[t] - mu[t]);
    const OutlierResult ro = outliers_3sigma(r, 3.0);
    std::vector<double> kept;
    kept.reserve(n);
    std::size_t j = 0;
    for (std::size_t t = 0; t < n; ++t) {
      if (w[t] == 0.0) continue;
      if (ro.keep[j] && phase[t] != Phase::settle) kept.push_back(r[j]);
      ++j;
    }
    if (kept.size() < 2) return std::unexpected(run_.name + ": no usable samples to verify on");
    return stddev(kept);
  }

  // Drops the cached column of the expression key (a candidate's, once it is scored).
  void forget(const std::string& key) { cols_.erase(key); }
  // The term's column evaluated by the caller on this run's signals (run_signals of the run at
  // this tref: the same numbers column() would make), kept unless it is there (or, while the
  // scorer reads the fit cache's columns, left to the fit cache: the caller puts it there).
  void put(const Term& t, const std::vector<double>& x) {
    if (fixed_->error.empty() && !shared_cols_) cols_.try_emplace(to_string(*t.expr), x);
  }
  // The term columns read in fc (this run's refits' cache, at this scorer's reference: made from
  // the same signals, the same numbers) rather than kept here, until called with null: the
  // scorers of the refits' threads then hold no copy of the columns the refits hold (the base's
  // and the candidate's; 12.6 MB on the 3-day run's two threads). Its own columns are dropped.
  // A column fc hands out stays valid for the calling thread until its next fit (FitCache::trim);
  // comp_std reads it before it returns.
  void read_columns_from(detail::FitCache* fc) {
    shared_cols_ = fc && fc->tref_c() == tref_c_ && &fc->run() == &run_ ? fc : nullptr;
    if (shared_cols_) cols_.clear();
  }

  // What the refits on this run share (the candidates' refits on the fit run: detail::fit_with),
  // made on first use, by the thread that then shares it (thread-safe once made); the refits'
  // whole-run Ljung-Box is not computed (they are only scored) and they are compared by BIC,
  // without standard errors (add_standard_errors for the one kept). It reads this scorer's
  // signals (not a copy of its own).
  // pad_lag_s: the max lag of the refits (FitOptions::max_lag_s), the lag extension each column
  // is kept in (FitCache).
  detail::FitCache& fit_cache(int pad_lag_s) {
    if (!fit_cache_) {
      fit_cache_ = std::make_unique<detail::FitCache>(run_, tref_c_, 8, fixed_->sig, pad_lag_s);
      fit_cache_->whole_run_whiteness = false;
      fit_cache_->standard_errors = false;
    }
    return *fit_cache_;
  }
  // The refits' cache released (its columns, spectra and sums: the step's refits are done).
  void drop_fit_cache() {
    if (shared_cols_ == fit_cache_.get()) shared_cols_ = nullptr;
    fit_cache_.reset();
  }

 private:
  struct Fixed {
    std::vector<double> w;
    std::vector<Phase> phase;
    std::shared_ptr<const RunSignals> sig;
    std::string error;
  };
  struct Share {};
  Scorer(Share, const RunData& run, double tref_c, std::shared_ptr<const Fixed> fixed) : run_(run), tref_c_(tref_c), fixed_(std::move(fixed)) {}
  static std::shared_ptr<const Fixed> make_fixed(const RunData& run, double tref_c, std::shared_ptr<const RunSignals> sig) {
    auto f = std::make_shared<Fixed>();
    f->w = detail::good_weights(run);
    f->phase = derive_phases(run);
    if (sig) {
      f->sig = std::move(sig);
    } else if (auto s = run_signals(run, tref_c)) {
      f->sig = std::make_shared<const RunSignals>(std::move(*s));
    } else {
      f->error = s.error().message;
    }
    return f;
  }
  std::expected<std::span<const double>, std::string> column(const Term& t) {
    const std::string key = to_string(*t.expr);
    auto it = cols_.find(key);
    if (it != cols_.end()) return std::span<const double>(it->second);
    if (shared_cols_)
      if (auto c = shared_cols_->column(t)) return *c;  // (an error: evaluated below, for its message)
    auto v = evaluate(*t.expr, fixed_->sig->view());
    if (!v) return std::unexpected("term '" + key + "': " + v.error());
    return std::span<const double>(cols_.emplace(key, std::move(*v)).first->second);
  }
  const RunData& run_;
  double tref_c_;
  std::shared_ptr<const Fixed> fixed_;
  std::map<std::string, std::vector<double>> cols_;
  std::unique_ptr<detail::FitCache> fit_cache_;
  detail::FitCache* shared_cols_ = nullptr;  // read_columns_from
};

// The model's terms with @auto terms frozen at their fitted lags.
std::vector<Term> frozen_terms(const Model& m);
// Lag parameters the model estimated (the paper method shares one).
int auto_lag_params(const Model& m);
bool has_key(const Model& m, const std::string& key);
// The base terms plus one at a fixed lag; when the new term is a model term again, the
// model's lags are frozen (the fit cannot separate the same term at two searched lags).
// Returns the terms and how many lag parameters were estimated outside the fit.
std::pair<TermList, int> extended_terms(const Model& base, const Term& extra, bool lag_scanned);

// The core's fit gives a non-finite gyro sample weight 0 but still multiplies it in (0 * NaN
// is NaN), so a run with a missing reading fails as "singular". A copy with such samples
// flagged missing and set to 0 has the same meaning and fits; runs without any are not copied.
const RunData& finite_gyro(const RunData& run, RunData& copy);

// The fit run as the candidates see it.
struct FitRun {
  std::shared_ptr<const RunSignals> sig;  // the fit run's scorer's (shared, read only)
  std::vector<double> w;
  std::vector<std::vector<double>> base_cols;  // the base model's regressors at fitted lags
};

// A candidate of the step: a library effect, a model term again at a second lag, an extra
// term asked for, or a term generated by the language search.
struct Cand {
  Term term;
  std::string expr, effect, explanation;
  bool repeat = false;
  bool generated = false;  // from the language search: screened by its lag scan's gain
  // What the screen found for a generated candidate it kept (the scan beside the base model,
  // the step's CandidateScan), handed on so that its evaluation does not scan it again: the
  // gain at its best lag. (Its column is evaluated again by evaluate_candidate: the same numbers,
  // and no run-length column per kept candidate held until its turn.)
  std::optional<CandidateScan::Gain> screened;
};

// What every candidate's evaluation reads (shared by the threads, read only).
struct StepContext {
  const Model& base;                 // the model refitted on the fit run
  const RunData& fit_run;
  std::span<const RunData> held_out;
  const DiagnoseOptions& o;
  const FitOptions& fo;
  const FitRun& fr;
  const CandidateScan& scan;         // beside the base model on the fit run
  double rms_fit_dph = 0.0;          // the base's compensated std on the fit run
  const std::vector<std::expected<double, std::string>>& held_before;  // the base's on each held-out run
  double ln_n = 0.0;                 // ln of the samples the base used (BIC's price of a parameter)
  // The gyro's slow noise (flicker, random walk) on the fit run and each held-out run, the mean
  // variance its floor gives over the run, (deg/h)^2 (0: none seen): a candidate must explain
  // more than that on every run, or a slow regressor that happens to follow one realisation of
  // the wander would be called an effect.
  double slow_fit_var = 0.0;
  const std::vector<double>* slow_held_var = nullptr;
};

struct EvaluatedCandidate {
  Candidate c;
  bool pruned = false;          // not refitted: its one-column update falls short (prune_fraction)
  // Detected: the lag of its column with the model's terms regressed out (the look-alikes' test),
  // made by the step once every candidate is refitted (not held beside the refits).
  std::optional<int> partial_lag;
};

// One candidate: its lag (scan, rescans as the refit moves the model's lags, lag 0 tried),
// the refit, its score on the fit run and every held-out run, and the verdict. fs and held_sc
// are this thread's scorers. fc: the fit run's refits' cache (the fit
// run's scorer's fit_cache(), shared by the step's threads).
EvaluatedCandidate evaluate_candidate(const StepContext& ctx, Cand& cd, Scorer& fs, std::vector<Scorer>& held_sc, detail::FitCache& fc);

}  // namespace fogbench::model::workbench::wbi
