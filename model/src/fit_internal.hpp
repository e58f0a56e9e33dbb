// Internal to model/: what the fit's files share (fit.cpp the entry point, fit_kernel.cpp the
// regression kernel over lags, fit_checks.cpp the checks, fit_paper.cpp and fit_joint.cpp the
// two methods). Not installed.
#pragma once

#include <cstddef>
#include <expected>
#include <limits>
#include <span>
#include <string>
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

// Least squares of y on [fixed columns, varying regressors all delayed by one shared lag i],
// for every i in [lo, hi], from normal equations whose sums come from the FFT; returns the lag
// of least SSE. wy_spec: the spectrum of w*y when the caller has it (else computed here).
ScanResult scan(const LagScanner& sc, std::span<const double> y, const Spectrum* wy_spec,
                const std::vector<Column>& fixed, const std::vector<const Lagged*>& varying, int lo, int hi);

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
std::expected<void, FitError> check_collinear(const std::vector<std::vector<double>>& cols,
                                              const std::vector<std::string>& names, std::span<const double> w,
                                              std::span<const std::size_t> lags = {});

// ---- shared by the two methods (fit.cpp) ----

// The run's signals and every term evaluated on them, unlagged.
struct Evaluated {
  RunSignals sig;
  std::vector<std::vector<double>> x;  // each term, unlagged
  std::vector<std::string> names;
};
std::expected<Evaluated, FitError> evaluate_terms(const RunData& run, const std::vector<Term>& terms, double tref_c);

// Standard errors and coefficient correlations from the prewhitened design, and the BIC of
// the innovations: common to both methods so that models compare on one footing.
void finish_stats(Model& m, const Evaluated& ev, std::span<const double> y, std::span<const double> w0, int n_auto_lags);

// ---- the methods (fit_paper.cpp, fit_joint.cpp) ----

// w: the samples' weights (good_weights); run.gyro_dph finite everywhere. progress: where
// the method is (stage, iterations), read by fit() when it fails; on success its termination
// (and for joint last_change and why) says how the method ended.
std::expected<Model, FitError> fit_paper(const RunData& run, const std::vector<Term>& terms, const FitOptions& o,
                                         const Evaluated& ev, std::vector<double> w, FitSummary& progress);
std::expected<Model, FitError> fit_joint(const RunData& run, const std::vector<Term>& terms, const FitOptions& o,
                                         const Evaluated& ev, std::vector<double> w, FitSummary& progress);

}  // namespace fogbench::model::detail
