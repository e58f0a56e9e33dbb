// Overlapping Allan deviation and the IEEE 952 Annex C noise terms (see allan.hpp).
#include "fogbench/model/allan.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace fogbench::model::allan {
namespace {

constexpr double kBiasInstabilityFactor = 0.664;  // sqrt(2 ln 2 / pi), IEEE 952 eq. (C.11)
constexpr double kSlopeTolerance = 0.25;          // |local slope - expected| accepted
constexpr double kFlatBand = 1.2;                 // a floor: sigma within 1.2 sigma_min ...
constexpr double kFlatSpan = 8.0;                 // ... over a factor 8 of tau

double relative_ci(const AdevPoint& p) {
  return p.adev_dph > 0.0 ? (p.ci_high_dph - p.adev_dph) / p.adev_dph : 0.0;
}

NoiseEstimate estimate(double value, const AdevPoint& tightest, double from_tau_s, double to_tau_s) {
  const double rel = relative_ci(tightest);
  return {value, std::max(0.0, value * (1.0 - rel)), value * (1.0 + rel), from_tau_s, to_tau_s};
}

std::string fmt(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3g", v);
  return buf;
}

}  // namespace

std::expected<std::vector<AdevPoint>, std::string> overlapping_adev(
    std::span<const double> rate_dph, double tau0_s, std::span<const std::int64_t> cluster_sizes) {
  const auto n = static_cast<std::int64_t>(rate_dph.size());
  if (!(tau0_s > 0.0) || !std::isfinite(tau0_s))
    return std::unexpected("tau0_s must be a positive number of seconds, got " + fmt(tau0_s));
  if (n < 3) return std::unexpected("Allan deviation needs at least 3 samples, got " + std::to_string(n));
  for (std::int64_t i = 0; i < n; ++i)
    if (!std::isfinite(rate_dph[static_cast<std::size_t>(i)]))
      return std::unexpected("rate sample " + std::to_string(i) + " is not a finite number");
  std::int64_t previous = 0;
  for (const auto m : cluster_sizes) {
    if (m < 1 || m > (n - 1) / 2)
      return std::unexpected("cluster size " + std::to_string(m) + " is outside 1.." +
                             std::to_string((n - 1) / 2) + " for " + std::to_string(n) + " samples");
    if (m <= previous)
      return std::unexpected("cluster sizes must increase: " + std::to_string(m) + " after " +
                             std::to_string(previous));
    previous = m;
  }

  // Angle in units of (deg/h)*tau0, accumulated in long double: 86,400 sums of values near a
  // bias of hundreds of deg/h lose digits in double before the second differences cancel them.
  // The mean rate is removed first; it cancels in the second difference anyway.
  long double mean = 0.0L;
  for (const double r : rate_dph) mean += r;
  mean /= static_cast<long double>(n);
  std::vector<long double> theta(static_cast<std::size_t>(n) + 1, 0.0L);
  for (std::int64_t i = 0; i < n; ++i)
    theta[static_cast<std::size_t>(i) + 1] =
        theta[static_cast<std::size_t>(i)] + (rate_dph[static_cast<std::size_t>(i)] - mean);

  std::vector<AdevPoint> out;
  out.reserve(cluster_sizes.size());
  for (const auto m : cluster_sizes) {
    const std::int64_t terms = n - 2 * m + 1;
    long double sum = 0.0L;
    for (std::int64_t k = 0; k < terms; ++k) {
      const auto d = theta[static_cast<std::size_t>(k + 2 * m)] -
                     2.0L * theta[static_cast<std::size_t>(k + m)] + theta[static_cast<std::size_t>(k)];
      sum += d * d;
    }
    // theta is in rate*tau0 units, so (theta diff / (m tau0))^2 * tau0^2 = diff^2 / m^2.
    const double avar = static_cast<double>(sum / (2.0L * static_cast<long double>(m) * m * terms));
    AdevPoint p;
    p.m = m;
    p.tau_s = static_cast<double>(m) * tau0_s;
    p.adev_dph = std::sqrt(avar);
    p.terms = terms;
    const double clusters = static_cast<double>(n) / static_cast<double>(m);
    const double rel = clusters > 1.0 ? 1.0 / std::sqrt(2.0 * (clusters - 1.0))
                                      : std::numeric_limits<double>::infinity();
    p.ci_low_dph = std::max(0.0, p.adev_dph * (1.0 - rel));
    p.ci_high_dph = p.adev_dph * (1.0 + rel);
    out.push_back(p);
  }
  return out;
}

std::vector<std::int64_t> octave_cluster_sizes(std::size_t n_samples) {
  std::vector<std::int64_t> m;
  const auto limit = (static_cast<std::int64_t>(n_samples) - 1) / 2;
  for (std::int64_t k = 1; k <= limit; k *= 2) m.push_back(k);
  return m;
}

NoiseTerms noise_terms(std::span<const AdevPoint> curve) {
  NoiseTerms t;
  if (curve.size() < 2) {
    t.arw_note = t.bias_instability_note = t.rrw_note = "the curve has fewer than 2 taus";
    return t;
  }
  for (const auto& p : curve)
    if (!(p.adev_dph > 0.0)) {
      t.arw_note = t.bias_instability_note = t.rrw_note =
          "sigma is 0 at tau " + fmt(p.tau_s) + " s: a constant series has no noise terms";
      return t;
    }
  const std::size_t n = curve.size();
  std::vector<double> slope(n - 1);
  for (std::size_t i = 0; i + 1 < n; ++i)
    slope[i] = std::log(curve[i + 1].adev_dph / curve[i].adev_dph) /
               std::log(curve[i + 1].tau_s / curve[i].tau_s);

  // Angle random walk: slope -1/2 from the shortest tau, over at most a decade of tau.
  if (std::abs(slope[0] + 0.5) > kSlopeTolerance) {
    t.arw_note = "the curve does not start with slope -1/2 (first slope " + fmt(slope[0]) + ")";
  } else {
    std::size_t last = 1;  // last point of the -1/2 stretch
    while (last < n - 1 && std::abs(slope[last] + 0.5) <= kSlopeTolerance &&
           curve[last + 1].tau_s <= 10.0 * curve[0].tau_s)
      ++last;
    double log_n = 0.0;  // log of sigma * sqrt(tau): (deg/h) sqrt(s)
    for (std::size_t i = 0; i <= last; ++i)
      log_n += std::log(curve[i].adev_dph) + 0.5 * std::log(curve[i].tau_s);
    log_n /= static_cast<double>(last + 1);
    // (deg/h) sqrt(s) = (deg/h) sqrt(h / 3600) = (1/60) deg/sqrt(h).
    t.arw_deg_per_sqrt_h = estimate(std::exp(log_n) / 60.0, curve[0], curve[0].tau_s, curve[last].tau_s);
  }

  // Bias instability: the minimum, if it lies inside the curve.
  const auto min_it = std::min_element(curve.begin(), curve.end(), [](const auto& a, const auto& b) {
    return a.adev_dph < b.adev_dph;
  });
  const auto i_min = static_cast<std::size_t>(min_it - curve.begin());
  if (i_min == n - 1) {
    t.bias_instability_note = "no minimum: sigma still falls at the longest tau, " +
                              fmt(curve[n - 1].tau_s) + " s (a longer record would show it)";
  } else if (i_min == 0) {
    t.bias_instability_note = "the minimum is at the shortest tau, " + fmt(curve[0].tau_s) +
                              " s: no white-noise region before it";
  } else {
    // Flat: sigma within 1.2 sigma_min over at least a factor 8 of tau (three octaves). The
    // bottom of white noise plus a rate random walk (sigma^2 = a/tau + b tau) stays within 1.2
    // over a factor 5.7 only, so that V is not taken for a floor.
    std::size_t lo = i_min, hi = i_min;
    while (lo > 0 && curve[lo - 1].adev_dph <= kFlatBand * min_it->adev_dph) --lo;
    while (hi + 1 < n && curve[hi + 1].adev_dph <= kFlatBand * min_it->adev_dph) ++hi;
    const bool flat = curve[hi].tau_s >= kFlatSpan * curve[lo].tau_s;
    t.bias_instability_dph = estimate(min_it->adev_dph / kBiasInstabilityFactor, *min_it,
                                      curve[lo].tau_s, curve[hi].tau_s);
    if (!flat)
      t.bias_instability_note = "the minimum at " + fmt(min_it->tau_s) + " s is not flat (within " +
                                "1.2x over " + fmt(curve[lo].tau_s) + ".." + fmt(curve[hi].tau_s) +
                                " s only): sigma_min / 0.664 is an upper bound of the bias instability";
  }

  // Rate random walk: the longest stretch of slope +1/2 after the minimum.
  std::size_t best_from = 0, best_len = 0;
  for (std::size_t i = i_min; i + 1 < n;) {
    if (std::abs(slope[i] - 0.5) > kSlopeTolerance) {
      ++i;
      continue;
    }
    std::size_t j = i;
    while (j + 1 < n && std::abs(slope[j] - 0.5) <= kSlopeTolerance) ++j;
    if (j - i > best_len) best_from = i, best_len = j - i;  // j - i segments, points i..j
    i = j;
  }
  if (best_len == 0) {
    t.rrw_note = "no +1/2 slope after the minimum";
  } else {
    double log_k = 0.0;  // log of sigma / sqrt(tau / 3): (deg/h) / sqrt(s)
    for (std::size_t i = best_from; i <= best_from + best_len; ++i)
      log_k += std::log(curve[i].adev_dph) - 0.5 * std::log(curve[i].tau_s / 3.0);
    log_k /= static_cast<double>(best_len + 1);
    // (deg/h) / sqrt(s) = (deg/h) / sqrt(h / 3600) = 60 (deg/h)/sqrt(h).
    t.rrw_dph_per_sqrt_h = estimate(std::exp(log_k) * 60.0, curve[best_from], curve[best_from].tau_s,
                                    curve[best_from + best_len].tau_s);
  }
  return t;
}

std::vector<Stretch> even_stretches(const RunData& run, std::size_t min_samples, bool all_phases) {
  std::vector<Stretch> out;
  const std::size_t n = run.size();
  const bool by_phase = run.has_phase() && !all_phases;
  auto usable = [&](std::size_t i) {
    return (!by_phase || run.phase[i] == Phase::hold) && !run.flagged(i) && std::isfinite(run.gyro_dph[i]);
  };
  std::size_t i = 0;
  while (i < n) {
    if (!usable(i)) {
      ++i;
      continue;
    }
    Stretch s;
    s.begin = i;
    s.phase = by_phase ? Phase::hold : Phase::unknown;
    std::size_t j = i + 1;
    double step_s = 0.0;
    for (; j < n && usable(j); ++j) {
      const double dt_s = run.time_s[j] - run.time_s[j - 1];
      if (j == i + 1) step_s = dt_s;
      if (!(dt_s > 0.0) || std::abs(dt_s - step_s) > 0.01 * step_s) break;
    }
    s.end = j;
    s.tau0_s = step_s > 0.0 ? step_s : 1.0;
    if (s.end - s.begin >= min_samples) out.push_back(s);
    i = j;
  }
  return out;
}

}  // namespace fogbench::model::allan
