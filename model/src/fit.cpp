// The fit's entry point and what both methods share: options, the run's signals, the terms
// evaluated, the closing statistics, prediction. The methods are fit_paper.cpp and
// fit_joint.cpp, the kernel fit_kernel.cpp, the checks fit_checks.cpp, verify verify.cpp.
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <sstream>

#include "common.hpp"
#include "fit_internal.hpp"
#include "fogbench/model/model.hpp"
#include "lsq.hpp"

namespace fogbench::model {

using detail::fail;

namespace {

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
  if (run.has_axis_thermistors()) {
    static constexpr const char* kAxisNames[2][3] = {{"T1x (t1_c)", "T1y (t1_y_c)", "T1z (t1_z_c)"},
                                                     {"T2x (t2_c)", "T2y (t2_y_c)", "T2z (t2_z_c)"}};
    for (std::size_t k = 0; k < 3; ++k) {
      if (run.axis_t1_c[k].size() != n || run.axis_t2_c[k].size() != n)
        return fail(FitError::Code::missing_signal, std::string("the per-axis thermistors of axis ") + "xyz"[k] + " are not one per sample");
      s.axis_t1[k].resize(n);
      s.axis_t2[k].resize(n);
      if (auto r = bridge(run.axis_t1_c[k], s.axis_t1[k], kAxisNames[0][k]); !r) return std::unexpected(r.error());
      if (auto r = bridge(run.axis_t2_c[k], s.axis_t2[k], kAxisNames[1][k]); !r) return std::unexpected(r.error());
    }
  }
  // Time since power-on is a clock, not a reading: taken as recorded (not offset by Tref, not
  // bridged); a run without it leaves it empty and a term using it says so.
  if (run.has_power_on() && run.since_power_on_s.size() == n) s.ton = run.since_power_on_s;
  return s;
}


namespace detail {

// The columns from cache (the signals are not copied: the methods read only the columns).
std::expected<Evaluated, FitError> evaluate_terms_with(FitCache& cache, const std::vector<Term>& terms) {
  Evaluated ev;
  for (const auto& t : terms) {
    auto v = cache.column(t);
    if (!v) return std::unexpected(v.error());
    ev.x.push_back(*v);  // the cache's column, pinned for this thread: not copied
    ev.names.push_back(to_string(t, false));
  }
  return ev;
}

std::expected<Evaluated, FitError> evaluate_terms(const RunData& run, const std::vector<Term>& terms, double tref_c) {
  Evaluated ev;
  auto s = run_signals(run, tref_c);
  if (!s) return std::unexpected(s.error());
  ev.sig = std::move(*s);
  for (const auto& t : terms) {
    auto v = evaluate(*t.expr, ev.sig.view());
    if (!v) return fail(FitError::Code::missing_signal, "term '" + to_string(t, false) + "': " + v.error());
    ev.own.push_back(std::move(*v));  // its buffer stays where it is as own grows
    ev.x.emplace_back(ev.own.back());
    ev.names.push_back(to_string(t, false));
  }
  return ev;
}

FitCache::FitCache(const RunData& run, double tref_c, std::size_t keep_columns, std::shared_ptr<const RunSignals> sig,
                   int pad_lag_s)
    : run_(run), tref_c_(tref_c), keep_(keep_columns), pad_(std::max(0, pad_lag_s)), sig_(std::move(sig)) {}

std::expected<const RunSignals*, FitError> FitCache::signals() {
  std::lock_guard lock(mu_);
  if (!sig_ && !sig_error_) {
    if (auto s = run_signals(run_, tref_c_)) sig_ = std::make_shared<const RunSignals>(std::move(*s));
    else sig_error_ = s.error();
  }
  if (sig_error_) return std::unexpected(*sig_error_);
  return sig_.get();
}

std::expected<FitCache::Entry*, FitError> FitCache::entry_locked(const Term& t, const std::span<const double>* x,
                                                                 std::unique_lock<std::mutex>& lock) {
  const std::string key = term_key(t);
  auto it = cols_.find(key);
  if (it == cols_.end()) {
    // Made without the lock (another thread may make the same column meanwhile: the first kept).
    lock.unlock();
    auto e = std::make_shared<Entry>();
    if (x) {
      e->padded = make_lagged(*x, pad_);
    } else {
      auto s = signals();
      if (!s) {
        lock.lock();
        return std::unexpected(s.error());
      }
      auto v = evaluate(*t.expr, (*s)->view());
      if (!v) {
        lock.lock();
        return fail(FitError::Code::missing_signal, "term '" + to_string(t, false) + "': " + v.error());
      }
      e->padded = make_lagged(*v, pad_);
    }
    lock.lock();
    it = cols_.try_emplace(key, std::move(e)).first;
  }
  it->second->used = ++clock_;
  pins_[std::this_thread::get_id()].push_back(it->second);
  return it->second.get();
}

std::expected<std::span<const double>, FitError> FitCache::column(const Term& t) {
  std::unique_lock lock(mu_);
  auto e = entry_locked(t, nullptr, lock);
  if (!e) return std::unexpected(e.error());
  return column_of(**e);
}

void FitCache::put(const Term& t, const std::vector<double>& x) {
  std::unique_lock lock(mu_);
  const std::span<const double> xs(x);
  (void)entry_locked(t, &xs, lock);
}

const Lagged& FitCache::lagged(const Term& t, std::span<const double> x, int max_lag, const LagScanner& sc) {
  // x is the term's column (column() gave it this fit, or a copy of it): the entry exists
  // unless the caller evaluated it elsewhere, then x is kept.
  std::unique_lock lock(mu_);
  Entry* e = *entry_locked(t, &x, lock);  // with x given, no error
  if (max_lag == pad_) {
    // The entry's own array; its spectrum transformed without the lock (the entry is pinned),
    // kept by the first thread that made it.
    if (e->padded.spec.empty()) {
      lock.unlock();
      Spectrum s;
      sc.lagged_spectrum(e->padded.ext, s);
      lock.lock();
      if (e->padded.spec.empty()) e->padded.spec = std::move(s);
    }
    return e->padded;
  }
  auto l = e->lagged.find(max_lag);
  if (l == e->lagged.end()) {
    // Extended and transformed without the lock, from the entry's column (pinned: it stays).
    lock.unlock();
    auto made = std::make_unique<const Lagged>(make_lagged(column_of(*e), max_lag));
    sc.ready(*made);
    lock.lock();
    l = e->lagged.try_emplace(max_lag, std::move(made)).first;
  }
  return *l->second;
}

const std::expected<PaperPrep, FitError>& FitCache::paper_prep(const FitOptions& o, const std::vector<double>& w) {
  // Made under the lock: once per step, and a thread asking for it meanwhile needs it anyway.
  std::lock_guard lock(mu_);
  const auto key = std::make_tuple(o.hold_s, o.ar_order, o.outlier_sigma, o.smooth_s, o.max_lag_s);
  auto it = paper_.find(key);
  if (it == paper_.end()) it = paper_.emplace(key, detail::paper_prep(run_, o, w)).first;
  return it->second;
}

void add_standard_errors(Model& m, FitCache& cache) {
  if (m.method != Method::paper || !m.fit.coef_corr.empty() || cache.tref_c() != m.tref_c) return;
  std::vector<Term> terms;
  bool any_auto = false;
  for (const auto& ft : m.terms) {
    terms.push_back(ft.term);
    any_auto = any_auto || ft.term.lag.automatic;
  }
  auto ev = evaluate_terms_with(cache, terms);
  if (!ev) return;
  finish_stats(m, *ev, cache.run().gyro_dph, good_weights(cache.run()), any_auto ? 1 : 0, true);
}

std::shared_ptr<const Spectrum> FitCache::spectrum(const std::string& key, const std::function<Spectrum()>& make) {
  {
    std::lock_guard lock(mu_);
    auto it = spectra_.find(key);
    if (it != spectra_.end()) {
      it->second.used = ++clock_;
      return it->second.s;
    }
  }
  auto made = std::make_shared<const Spectrum>(make());
  std::lock_guard lock(mu_);
  auto it = spectra_.find(key);  // another thread may have made it meanwhile: the first kept
  if (it == spectra_.end()) {
    while (spectra_.size() >= max_spectra) {
      auto oldest = spectra_.begin();
      for (auto o = spectra_.begin(); o != spectra_.end(); ++o)
        if (o->second.used < oldest->second.used) oldest = o;
      spectra_.erase(oldest);  // a scan holding it keeps it (shared)
    }
    it = spectra_.try_emplace(key, KeptSpectrum{std::move(made), 0}).first;
  }
  it->second.used = ++clock_;
  return it->second.s;
}

void FitCache::forget(const Term& t) {
  const std::string key = term_key(t);
  std::lock_guard lock(mu_);
  cols_.erase(key);
}

void FitCache::trim() {
  std::lock_guard lock(mu_);
  pins_.erase(std::this_thread::get_id());
  while (cols_.size() > keep_) {
    auto oldest = cols_.begin();
    for (auto it = cols_.begin(); it != cols_.end(); ++it)
      if (it->second->used < oldest->second->used) oldest = it;
    cols_.erase(oldest);  // a thread still reading it holds it (pins_)
  }
}

// Standard errors and coefficient correlations from the prewhitened design, and the BIC of
// the innovations: common to both methods so that models compare on one footing.
void finish_stats(Model& m, const Evaluated& ev, std::span<const double> y, std::span<const double> w0, int n_auto_lags, bool se) {
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
    // The design row only for the standard errors (a refit scored by BIC needs the RSS alone).
    if (se) {
      for (std::size_t j = 0; j < nt; ++j) {
        double f = x_at(j, t, 0);
        for (std::size_t i = 0; i < p; ++i) f -= m.ar[i] * x_at(j, t, i + 1);
        row[j + 1] = f;
      }
      ls.add(row, 0.0);
    }
    double a = e_recent[0];
    for (std::size_t i = 0; i < p; ++i) a -= m.ar[i] * e_recent[i + 1];
    rss += a * a;
    nw += 1.0;
  }
  const double nparams = static_cast<double>(k + p + static_cast<std::size_t>(n_auto_lags));
  const double s2 = nw > nparams ? rss / (nw - nparams) : 0.0;
  m.fit.coef_corr.assign(k, std::vector<double>(k, 0.0));
  if (!se) {
    m.fit.coef_corr.clear();  // not computed (add_standard_errors computes them)
  } else if (const Eigen::MatrixXd cov = ls.covariance(s2); cov.size() != 0) {
    m.mu0_se_dph = std::sqrt(std::max(0.0, cov(0, 0)));
    for (std::size_t j = 0; j < nt; ++j) m.terms[j].se_dph_per_unit = std::sqrt(std::max(0.0, cov(j + 1, j + 1)));
    for (std::size_t r = 0; r < k; ++r)
      for (std::size_t c = 0; c < k; ++c) {
        const double d = std::sqrt(cov(r, r) * cov(c, c));
        m.fit.coef_corr[r][c] = d > 0.0 ? cov(r, c) / d : (r == c ? 1.0 : 0.0);
      }
  }
  m.fit.bic = nw > 0 && rss > 0 ? nw * std::log(rss / nw) + nparams * std::log(nw) : 0.0;
}

}  // namespace detail

namespace {

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
  m.axis = run.axis;
}

}  // namespace

namespace {

// fit() without its summary on failure: `progress` follows it (stage, iterations).
std::expected<Model, FitError> fit_run(const RunData& run, const TermList& tl, const FitOptions& o, FitSummary& progress,
                                       detail::FitCache* cache) {
  progress.stage = "options";
  if (auto v = o.validate(); !v) return fail(FitError::Code::bad_options, v.error());
  const std::size_t n = run.size();
  if (run.gyro_dph.size() != n || run.t1_c.size() != n || run.t2_c.size() != n)
    return fail(FitError::Code::bad_options, "the run's columns have different lengths");
  const std::vector<Term>& terms = tl.terms;
  progress.stage = "checks";
  if (auto c = detail::check_terms(n, terms, o); !c) return std::unexpected(c.error());
  if (auto t = detail::check_time(run); !t) return std::unexpected(t.error());
  // A cache of another run or reference temperature is not used.
  if (cache && (&cache->run() != &run || cache->tref_c() != o.tref_c)) cache = nullptr;
  if (cache) cache->trim();
  auto ev = cache ? detail::evaluate_terms_with(*cache, terms) : detail::evaluate_terms(run, terms, o.tref_c);
  if (!ev) return std::unexpected(ev.error());
  std::size_t n_flagged = 0;
  std::vector<double> w = detail::good_weights(run, &n_flagged);
  // Before the fit, the columns at the lags that are known: a fixed lag as written, an @auto
  // term at 0. The same term again (a second thermal path, check_terms let it through: two
  // fixed lags that differ, or two @auto in a joint fit) is the same column until it is
  // delayed: a fixed copy is checked at its lag (and named with it), an @auto copy only at its
  // fitted lag below. The columns are copied only when a copy is left out.
  {
    std::vector<std::string> keys, names, memo_keys;
    for (const auto& t : terms) keys.push_back(term_key(t));
    std::vector<std::size_t> keep, lags;
    for (std::size_t j = 0; j < terms.size(); ++j) {
      const auto copies = std::count(keys.begin(), keys.end(), keys[j]);
      const bool later_copy = std::find(keys.begin(), keys.end(), keys[j]) != keys.begin() + static_cast<std::ptrdiff_t>(j);
      if (later_copy && terms[j].lag.automatic) continue;
      const int lag_s = terms[j].lag.automatic ? 0 : terms[j].lag.seconds;
      keep.push_back(j);
      lags.push_back(static_cast<std::size_t>(lag_s));
      names.push_back(copies > 1 && !terms[j].lag.automatic ? ev->names[j] + "@" + std::to_string(lag_s) : ev->names[j]);
      memo_keys.push_back(keys[j] + "@" + std::to_string(lag_s));
    }
    std::vector<std::span<const double>> subset;
    if (keep.size() < terms.size())
      for (std::size_t j : keep) subset.push_back(ev->x[j]);
    const auto& cols = keep.size() < terms.size() ? subset : ev->x;
    if (auto c = detail::check_collinear(cols, names, w, lags, cache ? &cache->collinear : nullptr, memo_keys); !c)
      return std::unexpected(c.error());
  }
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
  // The cache's paper step holds the run as given: a cleaned copy is fitted without it.
  auto m = o.method == Method::paper ? detail::fit_paper(*src, terms, o, *ev, w, progress, src == &run ? cache : nullptr)
                                     : detail::fit_joint(*src, terms, o, *ev, w, progress);
  if (!m) return m;
  progress.stage = "collinearity at the fitted lags";
  // A pair of @auto terms that are collinear only at their fitted lags is caught here.
  {
    std::vector<std::size_t> lags;
    std::vector<std::string> lagged_names, memo_keys;
    for (std::size_t j = 0; j < terms.size(); ++j) {
      lags.push_back(static_cast<std::size_t>(m->terms[j].term.lag.seconds));
      lagged_names.push_back(ev->names[j] + "@" + std::to_string(m->terms[j].term.lag.seconds));
      memo_keys.push_back(term_key(terms[j]) + "@" + std::to_string(m->terms[j].term.lag.seconds));
    }
    if (auto c = detail::check_collinear(ev->x, lagged_names, w, lags, cache ? &cache->collinear : nullptr, memo_keys); !c)
      return std::unexpected(c.error());
  }
  m->fit.n_flagged = n_flagged;
  m->tref_c = o.tref_c;
  m->max_lag_s = o.max_lag_s;
  m->smooth_s = o.smooth_s;
  m->hold_s = o.hold_s;
  fill_fitted_on(*m, run);
  return m;
}

std::expected<Model, FitError> fit_impl(const RunData& run, const TermList& tl, const FitOptions& o, detail::FitCache* cache) {
  FitSummary progress;
  progress.method = o.method;
  auto m = fit_run(run, tl, o, progress, cache);
  if (!m) {
    FitError e = std::move(m.error());
    e.summary = progress;
    e.summary.termination = FitTermination::failed;
    e.summary.why = e.message;
    return std::unexpected(std::move(e));
  }
  // The one whiteness statistic, over the whole run (the paper method's AR noise was fitted on
  // the opening hold alone; diagnose reads the same number).
  if (!cache || cache->whole_run_whiteness) {
    if (auto rw = run_whiteness(*m, run, 20)) {
      m->fit.ljung_box_q = rw->wh.lb.q;
      m->fit.ljung_box_p = rw->wh.lb.p_value;
    }
  }
  progress.stage = "done";
  m->fit.summary = progress;
  m->fit.iterations = progress.iterations;
  m->fit.converged = progress.converged();
  return m;
}

}  // namespace

std::expected<Model, FitError> fit(const RunData& run, const TermList& tl, const FitOptions& o) { return fit_impl(run, tl, o, nullptr); }

namespace detail {
std::expected<Model, FitError> fit_with(const RunData& run, const TermList& tl, const FitOptions& o, FitCache& cache) {
  return fit_impl(run, tl, o, &cache);
}
}  // namespace detail

std::string_view to_string(FitTermination t) {
  switch (t) {
    case FitTermination::converged: return "converged";
    case FitTermination::no_convergence: return "no_convergence";
    case FitTermination::failed: return "failed";
  }
  return "?";
}

std::string FitSummary::brief() const {
  std::string s = std::string(to_string(method)) + " fit ";
  switch (termination) {
    case FitTermination::converged: s += "converged"; break;
    case FitTermination::no_convergence: s += "NOT converged"; break;
    case FitTermination::failed: s += "failed" + (stage.empty() ? std::string() : " at " + stage); break;
  }
  if (method == Method::joint && iterations > 0) s += " after " + std::to_string(iterations) + (iterations == 1 ? " iteration" : " iterations");
  if (!why.empty()) s += ": " + why;
  return s;
}

std::expected<std::vector<std::vector<double>>, FitError> regressors(const Model& m, const RunData& run) {
  std::vector<Term> terms;
  for (const auto& t : m.terms) terms.push_back(t.term);
  auto ev = detail::evaluate_terms(run, terms, m.tref_c);
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

namespace detail {
std::expected<std::vector<std::vector<double>>, FitError> regressors_with(const Model& m, FitCache& cache) {
  if (cache.tref_c() != m.tref_c) return regressors(m, cache.run());
  const std::size_t n = cache.run().size();
  std::vector<std::vector<double>> cols;
  for (const auto& ft : m.terms) {
    auto x = cache.column(ft.term);
    if (!x) return std::unexpected(x.error());
    const auto lag = static_cast<std::size_t>(ft.term.lag.seconds);
    std::vector<double> c(n);
    for (std::size_t t = 0; t < n; ++t) c[t] = (*x)[t >= lag ? t - lag : 0];
    cols.push_back(std::move(c));
  }
  return cols;
}
}  // namespace detail

std::expected<std::vector<double>, FitError> predict(const Model& m, const RunData& run) {
  auto cols = regressors(m, run);
  if (!cols) return std::unexpected(cols.error());
  std::vector<double> mu(run.size(), m.mu0_dph);
  for (std::size_t j = 0; j < cols->size(); ++j)
    for (std::size_t t = 0; t < mu.size(); ++t) mu[t] += m.terms[j].coef * (*cols)[j][t];
  return mu;
}

}  // namespace fogbench::model
