// Internal to model/: what the fit's files share (fit.cpp the entry point, fit_kernel.cpp the
// regression kernel over lags, fit_checks.cpp the checks, fit_paper.cpp and fit_joint.cpp the
// two methods). Not installed.
#pragma once

#include <cstddef>
#include <cstdint>
#include <expected>
#include <functional>
#include <map>
#include <mutex>
#include <optional>
#include <thread>
#include <memory>
#include <limits>
#include <span>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "fogbench/model/model.hpp"
#include "lagscan.hpp"

namespace fogbench::model::detail {

// ---- the kernel (fit_kernel.cpp) ----

// A fixed column of the regression: a view of a series (a term at its lag, read in place from
// its Lagged extension), or a constant (the intercept).
struct Column {
  const double* v = nullptr;  // null when constant; else valid for t = 0..N-1
  double c = 0.0;
  bool constant() const { return v == nullptr; }
  double at(std::size_t t) const { return v ? v[t] : c; }
};
inline Column lagged_view(const Lagged& x, int max_lag, int lag) { return {x.ext.data() + (max_lag - lag), 0.0}; }

struct ScanResult {
  int lag = 0;
  std::vector<double> theta;  // fixed columns first, then the varying ones
  double sse = std::numeric_limits<double>::infinity();
  bool ok = false;
};

// A mutex for a memo held in a movable struct: a move leaves it behind (the object moved to
// has a fresh one). The memos of a FitCache are shared by the threads of a diagnose step.
struct MemoMutex {
  std::mutex m;
  MemoMutex() = default;
  MemoMutex(MemoMutex&&) noexcept {}
  MemoMutex& operator=(MemoMutex&&) noexcept { return *this; }
};

// The lag-dependent sums scan() made for named columns against one target (PaperPrep's z, one
// scanner): a refit of the same run with other terms beside them needs the same sums again (a
// diagnose step refits the base's terms beside each candidate), so they are kept by the columns'
// keys and reused as computed (the same numbers). Keys: a varying column's term key; a fixed
// column's term key with "@" and its lag.
struct ScanMemo {
  std::map<std::string, std::vector<double>> cvy, ones;                       // by the varying column
  std::map<std::pair<std::string, std::string>, std::vector<double>> cvf, gvv;  // (varying, fixed) and (varying, varying)
  // Entries of cvf beyond this are dropped all at once (each is max_lag + 1 sums; the
  // candidates' fixed columns at their lags are many, the base's few).
  static constexpr std::size_t max_pairs = 1024;  // about 5 MB with the default 600 s lags
  MemoMutex mu;  // held while the maps are read or changed (never while a sum is made)
};

// Least squares of y on [fixed columns, varying regressors all delayed by one shared lag i],
// for every i in [lo, hi], from normal equations whose sums come from the FFT; returns the lag
// of least SSE. wy_spec: the spectrum of w*y when the caller has it (else computed here).
// memo: the sums of named columns against this y and scanner (fixed_keys and varying_keys name
// the columns, an empty key is not kept); null: nothing kept.
ScanResult scan(const LagScanner& sc, std::span<const double> y, const Spectrum* wy_spec,
                const std::vector<Column>& fixed, const std::vector<const Lagged*>& varying, int lo, int hi,
                ScanMemo* memo = nullptr, std::span<const std::string> fixed_keys = {},
                std::span<const std::string> varying_keys = {});

// Least squares of y on fixed columns by the QR kernel (lsq.hpp): the coefficients and SSE the
// models report, at the lags the scan chose. lag is copied into the result.
ScanResult solve_at(std::span<const double> y, std::span<const double> w, const std::vector<Column>& cols, int lag = 0);

// AR(p) by least squares over the rows whose p+1 samples all have weight.
std::expected<ArFit, std::string> fit_ar_rows(std::span<const double> e, std::span<const double> w, int p);

// ---- the checks (fit_checks.cpp) ----

// The samples are 1 s apart.
std::expected<void, FitError> check_time(const RunData& run);
// The terms can be told apart (no term twice at one lag) and the run is long enough for them.
std::expected<void, FitError> check_terms(std::size_t n_samples, const std::vector<Term>& terms, const FitOptions& o);
// Names the terms that make the regression singular. Column j is read delayed by lags[j]
// samples (the first sample standing in before the start); no lags, no delay.
// memo, with keys naming each column at its lag (the term's key, "@", the lag): the weighted
// means and centred cross products already summed for these columns on this run and weights
// (a diagnose step checks the base's terms beside every candidate), reused as computed.
struct CollinearMemo {
  std::map<std::string, double> mean;
  std::map<std::pair<std::string, std::string>, double> cross;  // in the order the pair was summed
  static constexpr std::size_t max_entries = 1 << 14;           // dropped all at once beyond
  MemoMutex mu;  // held while the maps are read or changed (never while a sum is made)
};
std::expected<void, FitError> check_collinear(const std::vector<std::span<const double>>& cols,
                                              const std::vector<std::string>& names, std::span<const double> w,
                                              std::span<const std::size_t> lags = {}, CollinearMemo* memo = nullptr,
                                              std::span<const std::string> keys = {});

// ---- shared by the two methods (fit.cpp) ----

// The run's signals and every term evaluated on them, unlagged.
// x views the columns: those evaluated here are held in own; evaluate_terms_with's are the fit
// cache's, pinned for the calling thread until its next fit (FitCache::trim), so that a refit
// does not copy every column of the run. Not copyable (the views would point into the original).
struct Evaluated {
  RunSignals sig;
  std::vector<std::span<const double>> x;  // each term, unlagged
  std::vector<std::string> names;
  std::vector<std::vector<double>> own;    // the columns evaluated here (x's views into them)
  Evaluated() = default;
  Evaluated(Evaluated&&) = default;
  Evaluated& operator=(Evaluated&&) = default;
  Evaluated(const Evaluated&) = delete;
  Evaluated& operator=(const Evaluated&) = delete;
};
std::expected<Evaluated, FitError> evaluate_terms(const RunData& run, const std::vector<Term>& terms, double tref_c);

// Standard errors and coefficient correlations from the prewhitened design, and the BIC of
// the innovations: common to both methods so that models compare on one footing.
// se false: the BIC only (the same number), no standard errors or correlations (coef_corr left
// empty): a refit compared by BIC alone; add_standard_errors completes it.
void finish_stats(Model& m, const Evaluated& ev, std::span<const double> y, std::span<const double> w0, int n_auto_lags, bool se = true);

// ---- what the refits of one run share (fit.cpp; diagnose's candidates) ----

// The paper method's first step and the target of its second, which depend on the run and the
// options only: mu0 and the AR noise of the opening hold, the smoothed output less mu0 (z),
// the lag scanner of the run's weights and the spectrum of w*z.
struct PaperPrep {
  double mu0_dph = 0.0, sigma_a_dph = 0.0;
  std::vector<double> ar;
  std::size_t n_hold = 0, n_outliers = 0;
  bool stationary = false;
  double hold_lb_q = 0.0, hold_lb_p = 0.0;
  std::vector<double> z;
  std::unique_ptr<LagScanner> sc;
  Spectrum wz_spec;
  // scan()'s sums against z of the columns refitted so far (fit_paper with a FitCache).
  mutable ScanMemo memo;
};

// One run's refits with many term lists (diagnose refits the model with each candidate): the
// run's signals, each term's column (with its lag extension and spectrum) and the paper
// method's PaperPrep are computed once and reused, so that a refit costs only what differs.
// The numbers are the same as fit() computes, whatever the cache holds.
// Columns are kept for the most recent terms only (keep_columns), so memory stays a few columns.
// Thread-safe: the threads of a diagnose step share one (their refits then share what each
// computes). What it hands a thread (a column, a lag extension) stays valid until that thread's
// next trim(), whatever the other threads drop meanwhile; a value made by two threads at once
// is kept once (they are the same numbers). Its two switches are set before it is shared.
class FitCache {
 public:
  // sig: the run's signals at tref_c when the caller holds them (run_signals(run, tref_c)),
  // read instead of a copy of its own. pad_lag_s: the max lag (s) the refits scan (their
  // FitOptions::max_lag_s): each column is kept already extended for it (make_lagged's layout),
  // so that a column and its lag extension are one array, not two.
  FitCache(const RunData& run, double tref_c, std::size_t keep_columns = 8, std::shared_ptr<const RunSignals> sig = nullptr,
           int pad_lag_s = 0);
  const RunData& run() const { return run_; }
  double tref_c() const { return tref_c_; }
  // fit()'s Ljung-Box over the whole run (Model::fit.ljung_box_q/p); off for refits that are
  // only scored (BIC, coefficients, standard errors).
  bool whole_run_whiteness = true;
  // The paper method's standard errors and coefficient correlations; off for refits compared by
  // BIC alone (the model's fit.coef_corr is then empty), add_standard_errors completes the one kept.
  bool standard_errors = true;

  std::expected<const RunSignals*, FitError> signals();
  // The term's column, unlagged (evaluate on the run's signals); the error names the term.
  // A view of the cache's array, valid like the lag extensions (until this thread's next trim()).
  std::expected<std::span<const double>, FitError> column(const Term& t);
  // The term's column as the caller evaluated it on this run's signals (the same numbers
  // column() would make), kept unless the cache has it: a candidate's refits then do not
  // evaluate it again.
  void put(const Term& t, const std::vector<double>& x);
  // The column extended for lags up to max_lag (make_lagged), its spectrum for sc (the
  // scanner of this run and max_lag that reads it) made before it is handed out and kept with it.
  // At the cache's pad_lag_s this is the array the column lies in (no copy); at another max lag
  // an extension of its own.
  const Lagged& lagged(const Term& t, std::span<const double> x, int max_lag, const LagScanner& sc);
  // The paper method's first step for these options (w: good_weights of the run).
  const std::expected<PaperPrep, FitError>& paper_prep(const FitOptions& o, const std::vector<double>& w);
  // Drops the columns used least recently beyond keep_columns, and what this thread was handed
  // since its last trim (called by a thread between its fits only: the references handed out
  // stay valid within one fit).
  void trim();
  // Drops the term's column (with its lag extensions and their spectra) now rather than when it
  // is the least recently used beyond keep_columns: a candidate's, once it is scored. A thread
  // still reading it holds it (pins_); asked for again, it is made again (the same numbers).
  void forget(const Term& t);
  // The columns kept (a test's view of forget and trim).
  std::size_t columns() {
    std::lock_guard lock(mu_);
    return cols_.size();
  }
  // check_collinear's sums of this run's columns (fit() checks every refit twice).
  CollinearMemo collinear;
  // A spectrum made from this run's columns, kept by the caller's key (diagnose's rescans: the
  // weighted column of a term at its lag, CandidateScan), made by make() on first use; at most
  // max_spectra are kept, the least recently used dropped first (each is about 9 bytes a sample:
  // 2.3 MB on a 3-day run; 4 hold a rescan's three base columns and one more lag).
  std::shared_ptr<const Spectrum> spectrum(const std::string& key, const std::function<Spectrum()>& make);
  static constexpr std::size_t max_spectra = 4;

 private:
  struct Entry {
    // The column extended for lags up to pad_ (pad_ copies of its first value, then the column):
    // the column is its tail; its spectrum is made when lagged() is first asked for pad_ (set
    // once, under mu_, while empty: read only after lagged() has handed it out).
    Lagged padded;
    std::map<int, std::unique_ptr<const Lagged>> lagged;  // other max lags (added under mu_, never removed)
    std::uint64_t used = 0;
  };
  std::span<const double> column_of(const Entry& e) const {
    return std::span<const double>(e.padded.ext).subspan(static_cast<std::size_t>(pad_));
  }
  // The entry of t (made from x, or evaluated when x is null), pinned for this thread; under mu_.
  std::expected<Entry*, FitError> entry_locked(const Term& t, const std::span<const double>* x, std::unique_lock<std::mutex>& lock);
  const RunData& run_;
  double tref_c_;
  std::size_t keep_;
  int pad_;
  std::mutex mu_;  // guards every member below and the entries' maps
  std::uint64_t clock_ = 0;
  std::shared_ptr<const RunSignals> sig_;  // made on first use unless given
  std::optional<FitError> sig_error_;
  std::map<std::string, std::shared_ptr<Entry>> cols_;
  // The entries each thread was handed since its last trim(): kept alive for it if dropped.
  std::map<std::thread::id, std::vector<std::shared_ptr<Entry>>> pins_;
  std::map<std::tuple<int, int, double, int, int>, std::expected<PaperPrep, FitError>> paper_;
  struct KeptSpectrum {
    std::shared_ptr<const Spectrum> s;
    std::uint64_t used = 0;  // clock_ at its last lookup
  };
  std::map<std::string, KeptSpectrum> spectra_;
};

// fit() with the run's shared parts from cache (cache.run() must be run).
std::expected<Model, FitError> fit_with(const RunData& run, const TermList& tl, const FitOptions& o, FitCache& cache);
// The standard errors and coefficient correlations of a paper model fitted by fit_with with
// standard_errors off, exactly as the fit computes them (nothing when it has them).
void add_standard_errors(Model& m, FitCache& cache);
// regressors() with the columns from cache.
std::expected<std::vector<std::vector<double>>, FitError> regressors_with(const Model& m, FitCache& cache);

// ---- the methods (fit_paper.cpp, fit_joint.cpp) ----

// w: the samples' weights (good_weights); run.gyro_dph finite everywhere. progress: where
// the method is (stage, iterations), read by fit() when it fails; on success its termination
// (and for joint last_change and why) says how the method ended.
// cache: the run's shared parts (null: computed here).
std::expected<Model, FitError> fit_paper(const RunData& run, const std::vector<Term>& terms, const FitOptions& o,
                                         const Evaluated& ev, std::vector<double> w, FitSummary& progress, FitCache* cache = nullptr);
// The paper method's first step and target (PaperPrep), as fit_paper computes them.
std::expected<PaperPrep, FitError> paper_prep(const RunData& run, const FitOptions& o, const std::vector<double>& w);
std::expected<Model, FitError> fit_joint(const RunData& run, const std::vector<Term>& terms, const FitOptions& o,
                                         const Evaluated& ev, std::vector<double> w, FitSummary& progress);

}  // namespace fogbench::model::detail
