// The checks a fit makes before it starts and after the lags are chosen: 1 s samples, the
// terms' count and repetitions against the run's length, and collinear terms (named).
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <numeric>

#include "common.hpp"
#include "fit_internal.hpp"

namespace fogbench::model::detail {

std::expected<void, FitError> check_time(const RunData& run) {
  const std::size_t n = run.size();
  for (std::size_t t = 1; t < n; ++t) {
    const double dt = run.time_s[t] - run.time_s[t - 1];
    // A step of 1000 is time in milliseconds: resampling it "every 1 s" would invent 999 of
    // every 1000 samples, so the hint says to convert the unit instead.
    if (std::abs(dt - 1.0) > 0.01)
      return fail(FitError::Code::uneven_time,
                  "samples " + std::to_string(t) + " and " + std::to_string(t + 1) + " are " + std::to_string(dt) +
                      " s apart (at time_s " + std::to_string(run.time_s[t - 1]) + "); the model works on 1 s samples: " +
                      (std::abs(dt - 1000.0) <= 10.0
                           ? "time_s looks like milliseconds, convert it to seconds (fogctl: add --time-unit ms to the command)"
                           : "resample the run onto 1 s (fogctl: add --resample 1 to the command)"));
  }
  return {};
}

std::expected<void, FitError> check_terms(std::size_t n, const std::vector<Term>& terms, const FitOptions& o) {
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
  return {};
}

// Names the terms that make the regression singular: those with weight in the null vector
// of the correlation matrix of the columns. Column j is read delayed by lags[j] samples (the
// first sample standing in before the start), so lagged columns need no copies; no lags, no
// delay.
std::expected<void, FitError> check_collinear(const std::vector<std::span<const double>>& cols,
                                              const std::vector<std::string>& names, std::span<const double> w,
                                              std::span<const std::size_t> lags, CollinearMemo* memo,
                                              std::span<const std::string> keys) {
  const std::size_t m = cols.size();
  if (m == 0) return {};
  if (keys.size() != m) memo = nullptr;
  // The memo's maps are read and changed under its mutex (shared by a diagnose step's threads).
  if (memo) {
    std::lock_guard lock(memo->mu.m);
    if (memo->mean.size() + memo->cross.size() > CollinearMemo::max_entries) {
      memo->mean.clear();
      memo->cross.clear();
    }
  }
  const std::size_t n = w.size();
  // Column j at sample t is cols[j][t - lag_j], its first value before that; the sums below
  // take the few samples before the longest lag one by one, the rest as plain loops.
  std::vector<std::size_t> lag(m, 0);
  for (std::size_t j = 0; j < m && !lags.empty(); ++j) lag[j] = std::min(lags[j], n);
  const std::size_t head = m ? *std::max_element(lag.begin(), lag.end()) : 0;
  auto at = [&](std::size_t j, std::size_t t) { return cols[j][t >= lag[j] ? t - lag[j] : 0]; };
  const double sw = std::accumulate(w.begin(), w.end(), 0.0);
  std::vector<double> mean(m, 0.0), sd(m, 0.0);
  // A sum is the same whatever the head (the samples before it are summed one by one, in the
  // same order, the skipped ones adding 0), so a memo's sums are the ones computed here.
  for (std::size_t j = 0; j < m; ++j) {
    if (memo) {
      std::lock_guard lock(memo->mu.m);
      if (auto it = memo->mean.find(keys[j]); it != memo->mean.end()) {
        mean[j] = it->second;
        continue;
      }
    }
    double s = 0.0;
    for (std::size_t t = 0; t < head; ++t)
      if (w[t] != 0.0) s += w[t] * at(j, t);
    const double* x = cols[j].data();
    const std::size_t l = lag[j];
    for (std::size_t t = head; t < n; ++t) s += w[t] != 0.0 ? w[t] * x[t - l] : 0.0;
    mean[j] = s / sw;
    if (memo) {
      std::lock_guard lock(memo->mu.m);
      memo->mean.emplace(keys[j], mean[j]);
    }
  }
  // The centred cross products (two passes for accuracy: a term of large mean and small
  // spread loses nothing to cancellation); a weight of zero skips a sample, NaN and all.
  Eigen::MatrixXd C(static_cast<Eigen::Index>(m), static_cast<Eigen::Index>(m));
  for (std::size_t a = 0; a < m; ++a)
    for (std::size_t b = a; b < m; ++b) {
      if (memo) {
        std::lock_guard lock(memo->mu.m);
        if (auto it = memo->cross.find({keys[a], keys[b]}); it != memo->cross.end()) {
          C(static_cast<Eigen::Index>(a), static_cast<Eigen::Index>(b)) = it->second;
          continue;
        }
      }
      double c = 0.0;
      for (std::size_t t = 0; t < head; ++t)
        if (w[t] != 0.0) c += w[t] * (at(a, t) - mean[a]) * (at(b, t) - mean[b]);
      const double* xa = cols[a].data();
      const double* xb = cols[b].data();
      const std::size_t la = lag[a], lb = lag[b];
      const double ma = mean[a], mb = mean[b];
      for (std::size_t t = head; t < n; ++t) c += w[t] != 0.0 ? w[t] * (xa[t - la] - ma) * (xb[t - lb] - mb) : 0.0;
      C(static_cast<Eigen::Index>(a), static_cast<Eigen::Index>(b)) = c;
      if (memo) {
        std::lock_guard lock(memo->mu.m);
        memo->cross.emplace(std::make_pair(keys[a], keys[b]), c);
      }
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

}  // namespace fogbench::model::detail
