// Overlapping Allan deviation and the IEEE 952 Annex C noise terms (see allan.hpp).
#include "fogbench/model/allan.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <barrier>
#include <bit>
#include <boost/math/distributions/chi_squared.hpp>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <span>
#include <system_error>
#include <thread>
#include <utility>
#include <vector>

namespace fogbench::model::allan {
namespace {

constexpr double kBiasInstabilityFactor = 0.664;        // sqrt(2 ln 2 / pi), IEEE 952 eq. (C.11)
constexpr double kOneSigmaTail = 0.15865525393145707;   // (1 - erf(1/sqrt 2)) / 2: 68.27 % two-sided
constexpr double kVisibleShare = 0.5;                   // a term shows where it is half of sigma^2 ...
constexpr double kVisibleSe = 2.0;                      // ... and its fitted part exceeds 2 s.e.
constexpr int kFitIterations = 6;                       // weights and EDF from the previous fit

std::string fmt(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3g", v);
  return buf;
}

constexpr NoiseKind kKinds[] = {NoiseKind::white, NoiseKind::flicker, NoiseKind::random_walk};

// The basis of sigma^2(tau) = A/tau + F + C tau.
double basis(NoiseKind k, double tau_s) {
  switch (k) {
    case NoiseKind::white: return 1.0 / tau_s;
    case NoiseKind::flicker: return 1.0;
    case NoiseKind::random_walk: return tau_s;
  }
  return 0.0;
}

// 1-sigma (68.27 %) chi-square interval of a variance s2 estimated with edf degrees of freedom:
// edf s2 / chi2_{1-q}(edf) .. edf s2 / chi2_{q}(edf) (NIST SP 1065 eq. 45).
std::pair<double, double> chi2_interval(double s2, double edf) {
  const boost::math::chi_squared dist(edf);
  return {edf * s2 / boost::math::quantile(dist, 1.0 - kOneSigmaTail),
          edf * s2 / boost::math::quantile(dist, kOneSigmaTail)};
}

struct Subfit {
  bool ok = false;
  double cost = 0.0;
  std::array<double, 3> p{};
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
};

// Weighted least squares of y on the parts in `mask` (bit k: kKinds[k]); columns scaled to unit
// weighted norm so that 1/tau and tau over five decades do not ruin the conditioning.
Subfit solve_subset(unsigned mask, const std::vector<double>& tau, const std::vector<double>& y,
                    const std::vector<double>& w) {
  Subfit f;
  std::vector<int> cols;
  for (int k = 0; k < 3; ++k)
    if (mask & (1u << k)) cols.push_back(k);
  const auto n = static_cast<Eigen::Index>(y.size());
  const auto q = static_cast<Eigen::Index>(cols.size());
  if (n < q) return f;
  Eigen::MatrixXd x(n, q);
  Eigen::VectorXd b(n);
  Eigen::VectorXd scale(q);
  for (Eigen::Index c = 0; c < q; ++c) {
    double norm = 0.0;
    for (Eigen::Index i = 0; i < n; ++i) {
      const double v = basis(kKinds[cols[static_cast<std::size_t>(c)]], tau[static_cast<std::size_t>(i)]);
      norm += w[static_cast<std::size_t>(i)] * v * v;
    }
    scale(c) = norm > 0.0 ? 1.0 / std::sqrt(norm) : 1.0;
  }
  for (Eigen::Index i = 0; i < n; ++i) {
    const double sw = std::sqrt(w[static_cast<std::size_t>(i)]);
    for (Eigen::Index c = 0; c < q; ++c)
      x(i, c) = sw * basis(kKinds[cols[static_cast<std::size_t>(c)]], tau[static_cast<std::size_t>(i)]) * scale(c);
    b(i) = sw * y[static_cast<std::size_t>(i)];
  }
  const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(x);
  if (qr.rank() < q) return f;
  const Eigen::VectorXd ps = qr.solve(b);
  const Eigen::MatrixXd inv = (x.transpose() * x).inverse();
  for (Eigen::Index c = 0; c < q; ++c) {
    const auto k = static_cast<std::size_t>(cols[static_cast<std::size_t>(c)]);
    f.p[k] = ps(c) * scale(c);
    if (!(f.p[k] >= 0.0)) return f;  // outside the feasible set: another subset holds it at 0
    for (Eigen::Index d = 0; d < q; ++d)
      f.cov(static_cast<Eigen::Index>(k), cols[static_cast<std::size_t>(d)]) = inv(c, d) * scale(c) * scale(d);
  }
  f.cost = (x * ps - b).squaredNorm();
  f.ok = true;
  return f;
}

// Non-negative weighted least squares over the three parts: with three unknowns the optimum is
// the cheapest feasible unconstrained solution over the 7 subsets of free parts.
Subfit solve_nonnegative(const std::vector<double>& tau, const std::vector<double>& y, const std::vector<double>& w) {
  Subfit best;
  for (unsigned mask = 1; mask < 8; ++mask) {
    auto f = solve_subset(mask, tau, y, w);
    if (f.ok && (!best.ok || f.cost < best.cost)) best = f;
  }
  return best;
}

// EDF of sigma^2 at one point for the fitted noise mix: 1/edf = sum_k share_k / edf_k, exact
// where one type dominates.
double mixed_edf(const AvarFit& fit, const AdevPoint& p) {
  const std::int64_t n_samples = p.terms + 2 * p.m - 1;
  const double total = fit.total(p.tau_s);
  if (!fit.ok || !(total > 0.0)) return overlapping_edf(NoiseKind::white, n_samples, p.m);
  double inv = 0.0;
  for (const auto k : kKinds) inv += fit.part(k, p.tau_s) / total / overlapping_edf(k, n_samples, p.m);
  return 1.0 / inv;
}

std::string kind_name(NoiseKind k) {
  switch (k) {
    case NoiseKind::white: return "white noise (slope -1/2)";
    case NoiseKind::flicker: return "flicker noise (flat floor)";
    case NoiseKind::random_walk: return "rate random walk (slope +1/2)";
  }
  return "";
}

// Reads term k at the tau (not the longest) where its share of sigma^2 is >= 1/2 and its
// relative interval is narrowest; the part of sigma^2 there, (deg/h)^2, with its interval.
struct Reading {
  std::size_t i = 0;
  double part = 0.0, lo = 0.0, hi = 0.0, edf = 0.0, share = 0.0;
};
std::optional<Reading> read_term(NoiseKind k, std::span<const AdevPoint> curve, const AvarFit& fit,
                                 const Eigen::Matrix3d& cov, const std::vector<double>& edf, std::string& note) {
  const std::size_t n = curve.size();
  const double param = k == NoiseKind::white ? fit.white : k == NoiseKind::flicker ? fit.flicker : fit.walk;
  const double se = k == NoiseKind::white ? fit.white_se : k == NoiseKind::flicker ? fit.flicker_se : fit.walk_se;
  double top_share = 0.0, top_tau = 0.0;
  for (std::size_t i = 0; i + 1 < n; ++i) {
    const double sh = fit.part(k, curve[i].tau_s) / fit.total(curve[i].tau_s);
    if (sh > top_share) top_share = sh, top_tau = curve[i].tau_s;
  }
  if (!(param > 0.0)) {
    note = "no " + kind_name(k) + " in the fitted curve";
    return std::nullopt;
  }
  if (top_share < kVisibleShare) {
    note = kind_name(k) + " is under half of sigma^2 at every tau before the longest (" +
           fmt(100.0 * top_share) + " % at most, at " + fmt(top_tau) + " s)";
    return std::nullopt;
  }
  if (!(param > kVisibleSe * se)) {
    note = kind_name(k) + ": its fitted part is within 2 standard errors of 0";
    return std::nullopt;
  }
  std::optional<Reading> best;
  double best_width = 0.0;
  const auto ki = static_cast<Eigen::Index>(k == NoiseKind::white ? 0 : k == NoiseKind::flicker ? 1 : 2);
  for (std::size_t i = 0; i + 1 < n; ++i) {
    const double tau = curve[i].tau_s, total = fit.total(tau), mine = fit.part(k, tau);
    if (mine / total < kVisibleShare) continue;
    const double s2 = curve[i].adev_dph * curve[i].adev_dph;
    const auto [lo, hi] = chi2_interval(s2, edf[i]);
    // The other parts are subtracted as fitted; their standard error widens the interval.
    Eigen::Vector3d g(1.0 / tau, 1.0, tau);
    g(ki) = 0.0;
    const double var_others = std::max(0.0, g.dot(cov * g));
    const double others = total - mine;
    Reading r;
    r.i = i;
    r.part = s2 - others;
    r.lo = r.part - std::sqrt((s2 - lo) * (s2 - lo) + var_others);
    r.hi = r.part + std::sqrt((hi - s2) * (hi - s2) + var_others);
    r.edf = edf[i];
    r.share = mine / total;
    const double width = (r.hi - r.lo) / mine;
    if (!best || width < best_width) best = r, best_width = width;
  }
  return best;
}

NoiseEstimate estimate_of(const Reading& r, const AdevPoint& p, double value, double low, double high) {
  NoiseEstimate e;
  e.value = value;
  e.ci_low = low;
  e.ci_high = high;
  e.from_tau_s = e.to_tau_s = p.tau_s;
  e.edf = r.edf;
  e.share = r.share;
  return e;
}

// The squared differences are summed in blocks of this many; the blocks' sums in long double.
constexpr std::int64_t kSumBlock = 4096;
// Independent partial sums in a block (a multiple of the widest vector's doubles), so the
// compiler vectorises the sum without reordering one accumulator's additions.
constexpr std::int64_t kLanes = 8;

// sum_k term(k) for k < len in kLanes partial sums; term may also write (the doubling). Inlined
// into each kernel below, so that it is compiled for each of the kernel's targets.
template <class Term>
[[gnu::always_inline]] inline double lane_pass(std::int64_t len, Term term) {
  std::array<double, kLanes> acc{};
  std::int64_t k = 0;
  for (; k + kLanes <= len; k += kLanes)
    for (std::int64_t j = 0; j < kLanes; ++j) acc[static_cast<std::size_t>(j)] += term(k + j);
  double sum = 0.0;
  for (; k < len; ++k) sum += term(k);
  for (const double v : acc) sum += v;
  return sum;
}

// The kernels: compiled for AVX2 as well as the baseline, chosen at load time by the CPU (GCC's
// target_clones); the passes are bound by arithmetic once their data is in cache, so the
// vector width is their speed. a and b are the window sums S_m(k) and S_m(k + m) (b = a + m:
// they overlap, both read); out, where written, overlaps neither.

// sum_k x[k] for k < n.
[[gnu::target_clones("avx2", "default")]] double lane_sum(const double* x, std::int64_t n) {
  return lane_pass(n, [x](std::int64_t k) { return x[k]; });
}

// sum_k (b[k] - a[k])^2 for k < len.
[[gnu::target_clones("avx2", "default")]] double squares(const double* __restrict a, const double* __restrict b, std::int64_t len) {
  return lane_pass(len, [a, b](std::int64_t k) {
    const double d = b[k] - a[k];
    return d * d;
  });
}

// The same, and S_2m(k) = a[k] + b[k] into out in the same pass.
[[gnu::target_clones("avx2", "default")]] double squares_and_sums(const double* __restrict a, const double* __restrict b,
                                                                   double* __restrict out, std::int64_t len) {
  return lane_pass(len, [a, b, out](std::int64_t k) {
    const double d = b[k] - a[k];
    out[k] = a[k] + b[k];
    return d * d;
  });
}

// The same with S_2m written over S_m (out = a), for len <= m: b's range lies past the one
// written.
[[gnu::target_clones("avx2", "default")]] double squares_and_sums_in_place(double* a, const double* __restrict b, std::int64_t len) {
  return lane_pass(len, [a, b](std::int64_t k) {
    const double d = b[k] - a[k];
    a[k] += b[k];
    return d * d;
  });
}

// The octaves done chunk by chunk (blocked_octaves): up to this cluster size, in chunks of this
// many starting indices (a multiple of kSumBlock, so the blocks are those of the whole-array
// pass); a chunk and its halo of 2 kBlockedMaxM sums, twice (the pass's input and output), take
// about 650 kB, within a core's L2 cache.
constexpr std::int64_t kBlockedMaxM = 4096;
constexpr std::int64_t kChunk = 8 * kSumBlock;

// The octaves m = 1, 2, ..., 2^(levels-1) in one pass over the run, where the whole-array passes
// would make two per octave through the last-level cache: for each chunk of kChunk starting
// indices, its rates and a halo of 2^levels after it, less the mean, are copied to a scratch;
// each octave's squared differences over the chunk are summed (in blocks of kSumBlock at the
// same indices as the whole-array pass) while the window sums are doubled into the other scratch
// (S_2m(k) = S_m(k) + S_m(k + m)). Returns each octave's sum of squared differences. With `next`
// not null, S_(2^levels)(k) for k = 0 .. n - 2^levels is written there, the start of the longer
// octaves.
// Only the chunks whose first index lies in [from, to) (multiples of kChunk) when given: the two
// halves of a long run (octaves_in_halves) each do theirs.
std::vector<long double> blocked_octaves(std::span<const double> rate_dph, double mean, int levels, double* next,
                                         std::int64_t from = 0, std::int64_t to = -1) {
  const auto n = static_cast<std::int64_t>(rate_dph.size());
  if (to < 0) to = n;
  const std::int64_t halo = std::int64_t{1} << levels;
  std::vector<long double> sums(static_cast<std::size_t>(levels), 0.0L);
  const auto scratch_size = static_cast<std::size_t>(std::min(n, kChunk + halo));
  const std::unique_ptr<double[]> scratch_a(new double[scratch_size]), scratch_b(new double[scratch_size]);
  for (std::int64_t c0 = from; c0 < std::min(n, to); c0 += kChunk) {
    const std::int64_t c1 = std::min(n, c0 + kChunk);
    double* a = scratch_a.get();  // a[j] is S_m(c0 + j)
    double* b = scratch_b.get();
    std::int64_t valid = std::min(n, c1 + halo) - c0;  // a[j] holds S_m(c0 + j) for j < valid
    for (std::int64_t j = 0; j < valid; ++j) a[j] = rate_dph[static_cast<std::size_t>(c0 + j)] - mean;
    for (int level = 0; level < levels; ++level) {
      const std::int64_t m = std::int64_t{1} << level;
      // This chunk's starting indices of m's second differences: c0 .. terms_end - 1. A chunk
      // holds them all, as 2m <= halo.
      const std::int64_t terms = std::max<std::int64_t>(0, std::min(c1, n - 2 * m + 1) - c0);
      long double& sum = sums[static_cast<std::size_t>(level)];
      for (std::int64_t j0 = 0; j0 < terms; j0 += kSumBlock)
        sum += squares_and_sums(a + j0, a + j0 + m, b + j0, std::min(kSumBlock, terms - j0));
      valid -= m;  // S_2m(c0 + j) needs S_m up to c0 + j + m
      for (std::int64_t j = terms; j < valid; ++j) b[j] = a[j] + a[j + m];
      std::swap(a, b);
    }
    if (next != nullptr)
      for (std::int64_t k = c0; k < std::min(c1, n - halo + 1); ++k) next[k] = a[k - c0];
  }
  return sums;
}

// Runs at least this long (samples) are done by octaves_in_halves, on two threads where the
// machine has two cores: the octaves' passes are most of fogctl allan's time on a long run.
constexpr std::int64_t kHalvesMinSamples = std::int64_t{1} << 18;

// Every octave m = 1, 2, ..., 2^(levels-1) of a long run (issue 30, point 3), its starting
// indices in two halves that two threads can do side by side: the leading octaves
// (blocked_octaves) by chunks, the first half's chunks and the second's; each longer octave's
// terms split at h (a multiple of kSumBlock), S_2m doubled in place over S_m in each half. The
// first half's last m doublings read S_m(h .. h + m), which the second half overwrites: those m
// sums are copied aside before either half starts the octave (`boundary`). The split is the same
// whether one thread or two do it, and each octave's sum is the first half's plus the second's,
// so the deviations do not depend on the machine's cores.
std::vector<long double> octaves_in_halves(std::span<const double> rate_dph, double mean, int levels, bool two_threads) {
  const auto n = static_cast<std::int64_t>(rate_dph.size());
  const int leading = std::min(levels, std::countr_zero(static_cast<std::uint64_t>(kBlockedMaxM)) + 1);
  const bool more = leading < levels;
  const std::unique_ptr<double[]> window(more ? new double[static_cast<std::size_t>(n)] : nullptr);
  double* s = window.get();
  const std::int64_t chunks = (n + kChunk - 1) / kChunk;
  const std::int64_t chunk_split = chunks / 2 * kChunk;
  std::array<std::vector<long double>, 2> sums;
  for (auto& v : sums) v.assign(static_cast<std::size_t>(levels), 0.0L);
  // The first m of the longest doubling octave at most (m <= n / 4 when 2m is an octave too).
  std::vector<double> boundary(more ? static_cast<std::size_t>(n / 4 + 1) : 0);
  const auto split_of = [n](std::int64_t m) { return (n - 2 * m + 1) / 2 / kSumBlock * kSumBlock; };
  const auto save_boundary = [&](int level) {
    const std::int64_t m = std::int64_t{1} << level;
    if (level + 1 < levels) std::copy(s + split_of(m), s + split_of(m) + m, boundary.begin());
  };
  // One half's share of octave `level` >= leading.
  const auto long_octave = [&](int level, int half) {
    const std::int64_t m = std::int64_t{1} << level;
    const std::int64_t terms = n - 2 * m + 1, h = split_of(m);
    const bool doubling = level + 1 < levels;
    long double& sum = sums[static_cast<std::size_t>(half)][static_cast<std::size_t>(level)];
    for (std::int64_t k0 = half == 0 ? 0 : h; k0 < (half == 0 ? h : terms); k0 += kSumBlock) {
      const std::int64_t len = std::min(kSumBlock, terms - k0);
      // m and h are multiples of kSumBlock: a block's S_m(k + m) lie wholly below h or from h on.
      const double* b = half == 0 && doubling && k0 + m >= h ? boundary.data() + (k0 + m - h) : s + k0 + m;
      sum += doubling ? squares_and_sums_in_place(s + k0, b, len) : squares(s + k0, b, len);
    }
  };
  const auto run = [&](int half, std::barrier<>* sync) {
    sums[static_cast<std::size_t>(half)] =
        blocked_octaves(rate_dph, mean, leading, s, half == 0 ? 0 : chunk_split, half == 0 ? chunk_split : n);
    sums[static_cast<std::size_t>(half)].resize(static_cast<std::size_t>(levels), 0.0L);
    for (int level = leading; level < levels; ++level) {
      if (sync != nullptr) {
        sync->arrive_and_wait();  // S_m complete in both halves
        if (half == 1) save_boundary(level);
        sync->arrive_and_wait();  // the boundary saved before the second half writes over it
      }
      long_octave(level, half);
    }
  };
  if (two_threads) {
    std::barrier<> sync(2);
    std::thread second;
    try {
      second = std::thread(run, 1, &sync);
    } catch (const std::system_error&) {  // no thread to be had: one thread does both halves
      two_threads = false;
    }
    if (two_threads) {
      run(0, &sync);
      second.join();
    }
  }
  if (!two_threads) {
    sums[0] = blocked_octaves(rate_dph, mean, leading, s, 0, chunk_split);
    sums[1] = blocked_octaves(rate_dph, mean, leading, s, chunk_split, n);
    for (auto& v : sums) v.resize(static_cast<std::size_t>(levels), 0.0L);
    for (int level = leading; level < levels; ++level) {
      save_boundary(level);
      long_octave(level, 0);
      long_octave(level, 1);
    }
  }
  std::vector<long double> total(static_cast<std::size_t>(levels));
  for (std::size_t l = 0; l < total.size(); ++l) total[l] = sums[0][l] + sums[1][l];
  return total;
}

// The Allan deviation at cluster size m of n samples from the sum of its squared differences.
AdevPoint point_of(std::int64_t m, std::int64_t n, double tau0_s, long double sum) {
  const std::int64_t terms = n - 2 * m + 1;
  // theta is in rate*tau0 units, so (theta diff / (m tau0))^2 * tau0^2 = diff^2 / m^2.
  const double avar = static_cast<double>(sum / (2.0L * static_cast<long double>(m) * m * terms));
  AdevPoint p;
  p.m = m;
  p.tau_s = static_cast<double>(m) * tau0_s;
  p.adev_dph = std::sqrt(avar);
  p.terms = terms;
  const double clusters = static_cast<double>(n) / static_cast<double>(m);
  const double rel = clusters > 1.0 ? 1.0 / std::sqrt(2.0 * (clusters - 1.0)) : std::numeric_limits<double>::infinity();
  p.ci_low_dph = std::max(0.0, p.adev_dph * (1.0 - rel));
  p.ci_high_dph = p.adev_dph * (1.0 + rel);
  return p;
}

}  // namespace

double AvarFit::part(NoiseKind k, double tau_s) const {
  switch (k) {
    case NoiseKind::white: return white / tau_s;
    case NoiseKind::flicker: return flicker;
    case NoiseKind::random_walk: return walk * tau_s;
  }
  return 0.0;
}

double overlapping_edf(NoiseKind kind, std::int64_t n_samples, std::int64_t m) {
  const double big_n = static_cast<double>(n_samples) + 1.0;  // angle (phase) points
  const double md = static_cast<double>(m);
  double edf = 1.0;
  switch (kind) {
    case NoiseKind::white:
      edf = (3.0 * (big_n - 1.0) / (2.0 * md) - 2.0 * (big_n - 2.0) / big_n) * 4.0 * md * md / (4.0 * md * md + 5.0);
      break;
    case NoiseKind::flicker:
      edf = m == 1 ? 2.0 * (big_n - 2.0) * (big_n - 2.0) / (2.3 * big_n - 4.9)
                   : 5.0 * big_n * big_n / (4.0 * md * (big_n + 3.0 * md));
      break;
    case NoiseKind::random_walk:
      edf = (big_n - 2.0) / (md * (big_n - 3.0) * (big_n - 3.0)) *
            ((big_n - 1.0) * (big_n - 1.0) - 3.0 * md * (big_n - 1.0) + 4.0 * md * md);
      break;
  }
  return std::isfinite(edf) ? std::max(1.0, edf) : 1.0;
}

std::expected<std::vector<AdevPoint>, std::string> overlapping_adev(
    std::span<const double> rate_dph, double tau0_s, std::span<const std::int64_t> cluster_sizes) {
  const auto n = static_cast<std::int64_t>(rate_dph.size());
  if (!(tau0_s > 0.0) || !std::isfinite(tau0_s))
    return std::unexpected("tau0_s must be a positive number of seconds, got " + fmt(tau0_s));
  if (n < 3) return std::unexpected("Allan deviation needs at least 3 samples, got " + std::to_string(n));
  // The mean rate, deg/h, in lanes of double (vectorised): it cancels in the second differences,
  // so its own rounding does not reach the deviation. A sum that is not finite has a sample that
  // is not (or rates near 1e308): found and named.
  const double sum_dph = lane_sum(rate_dph.data(), n);
  if (!std::isfinite(sum_dph)) {
    for (std::int64_t i = 0; i < n; ++i)
      if (!std::isfinite(rate_dph[static_cast<std::size_t>(i)]))
        return std::unexpected("rate sample " + std::to_string(i) + " is not a finite number");
    return std::unexpected("the rate samples' sum overflows a double: rates near 1e308 deg/h are not a gyro's");
  }
  const double mean = sum_dph / static_cast<double>(n);
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

  // A long run at octave taus only (octave_cluster_sizes: fogctl allan, the report): in halves.
  bool all_octaves = n >= kHalvesMinSamples;
  for (std::size_t i = 0; all_octaves && i < cluster_sizes.size(); ++i)
    all_octaves = cluster_sizes[i] == std::int64_t{1} << i;
  if (all_octaves && !cluster_sizes.empty()) {
    const auto sums = octaves_in_halves(rate_dph, mean, static_cast<int>(cluster_sizes.size()),
                                        std::thread::hardware_concurrency() >= 2);
    std::vector<AdevPoint> out;
    for (std::size_t level = 0; level < sums.size(); ++level)
      out.push_back(point_of(cluster_sizes[level], n, tau0_s, sums[level]));
    return out;
  }

  // The second difference of the angle at cluster size m is a difference of two window sums,
  // S_m(k + m) - S_m(k), S_m(k) the sum of the m rates from k (in (deg/h)*tau0). The window sums
  // are kept, not the angle: an angle accumulated over 864,000 samples of a drifting gyro
  // reaches 1e6 and more, and its second differences at short taus would lose 7 of double's 16
  // digits. The mean rate is removed first (it cancels in the second difference anyway). When the next cluster size is a doubling, S_2m(k) = S_m(k) + S_m(k + m) is made in
  // the same pass as m's squared differences, into a second array (no aliasing: the pass is
  // vectorised whole); another m is summed afresh from the angle in long double (half-octave
  // taus on short holds). What this replaced, a long-double loop over the angle for every tau,
  // took 84 ms at 864,000 samples and 19 taus (docs/performance.md, "Allan deviation").
  std::vector<long double> theta;  // the angle, made only for a cluster size that does not double
  // S_m(k), k = 0 .. n - m, and S_2m as the pass makes it; left as allocated where the leading
  // octaves' pass fills it.
  std::unique_ptr<double[]> window(new double[static_cast<std::size_t>(n)]), doubled;
  double* s = window.get();
  std::int64_t window_m = 1;
  // The leading cluster sizes 1, 2, 4, ... up to kBlockedMaxM, chunk by chunk (blocked_octaves).
  std::size_t leading = 0;
  while (leading < cluster_sizes.size() && cluster_sizes[leading] == (std::int64_t{1} << leading) &&
         cluster_sizes[leading] <= kBlockedMaxM)
    ++leading;
  std::vector<long double> leading_sums;
  if (leading > 0) {
    const bool more = leading < cluster_sizes.size();
    leading_sums = blocked_octaves(rate_dph, mean, static_cast<int>(leading), more ? s : nullptr);
    window_m = std::int64_t{1} << leading;
  } else {
    for (std::int64_t i = 0; i < n; ++i) s[i] = rate_dph[static_cast<std::size_t>(i)] - mean;
  }
  const auto sums_from_angle = [&](std::int64_t m) {
    if (theta.empty()) {
      theta.assign(static_cast<std::size_t>(n) + 1, 0.0L);
      for (std::int64_t i = 0; i < n; ++i)
        theta[static_cast<std::size_t>(i) + 1] =
            theta[static_cast<std::size_t>(i)] + (static_cast<long double>(rate_dph[static_cast<std::size_t>(i)]) - mean);
    }
    for (std::int64_t k = 0; k + m <= n; ++k)
      s[k] = static_cast<double>(theta[static_cast<std::size_t>(k + m)] - theta[static_cast<std::size_t>(k)]);
    window_m = m;
  };
  // S_2m from S_m into the other array, without the squares (a doubling no cluster size asks for).
  const auto double_windows = [&] {  // forward order: S_m(k + m) is read before it is overwritten
    const std::int64_t len = n - 2 * window_m + 1;
    for (std::int64_t k = 0; k < len; ++k) s[k] += s[k + window_m];
    window_m *= 2;
  };

  std::vector<AdevPoint> out;
  out.reserve(cluster_sizes.size());
  for (std::size_t level = 0; level < cluster_sizes.size(); ++level) {
    const std::int64_t m = cluster_sizes[level];
    if (level < leading) {
      out.push_back(point_of(m, n, tau0_s, leading_sums[level]));
      continue;
    }
    while (window_m < m && 2 * window_m <= m) double_windows();
    if (window_m != m) sums_from_angle(m);
    const std::int64_t terms = n - 2 * m + 1;
    // The next cluster size is reached by doubling: S_2m made in this pass, over S_m where a
    // block's writes stay below its reads (m >= kSumBlock, forward order), else into the other
    // array.
    const bool doubling = level + 1 < cluster_sizes.size() && cluster_sizes[level + 1] >= 2 * m;
    const bool in_place = m >= kSumBlock;
    if (doubling && !in_place && !doubled) doubled.reset(new double[static_cast<std::size_t>(n)]);
    // Summed in blocks, the blocks' sums added in long double: the rounding of 864,000 squares
    // stays near one block's.
    long double sum = 0.0L;
    for (std::int64_t k0 = 0; k0 < terms; k0 += kSumBlock) {
      const std::int64_t len = std::min(kSumBlock, terms - k0);
      if (!doubling)
        sum += squares(s + k0, s + k0 + m, len);
      else if (in_place)
        sum += squares_and_sums_in_place(s + k0, s + k0 + m, len);
      else
        sum += squares_and_sums(s + k0, s + k0 + m, doubled.get() + k0, len);
    }
    if (doubling) {
      if (!in_place) {
        window.swap(doubled);
        s = window.get();
      }
      window_m = 2 * m;
    }
    out.push_back(point_of(m, n, tau0_s, sum));
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
  std::vector<double> tau(n), s2(n), edf(n), model(n), w(n);
  for (std::size_t i = 0; i < n; ++i) {
    tau[i] = curve[i].tau_s;
    s2[i] = model[i] = curve[i].adev_dph * curve[i].adev_dph;
    edf[i] = overlapping_edf(NoiseKind::white, curve[i].terms + 2 * curve[i].m - 1, curve[i].m);
  }
  // Weighted least squares with each point's variance 2 sigma^4 / edf, sigma^2 and the EDF's
  // noise mix taken from the previous fit (the measured sigma^2 at first).
  Subfit sub;
  AvarFit& fit = t.fit;
  for (int iter = 0; iter < kFitIterations; ++iter) {
    for (std::size_t i = 0; i < n; ++i) w[i] = edf[i] / (2.0 * model[i] * model[i]);
    sub = solve_nonnegative(tau, s2, w);
    if (!sub.ok) break;
    fit.ok = true;
    fit.white = sub.p[0], fit.flicker = sub.p[1], fit.walk = sub.p[2];
    fit.white_se = std::sqrt(std::max(0.0, sub.cov(0, 0)));
    fit.flicker_se = std::sqrt(std::max(0.0, sub.cov(1, 1)));
    fit.walk_se = std::sqrt(std::max(0.0, sub.cov(2, 2)));
    for (std::size_t i = 0; i < n; ++i) {
      const double m = fit.total(tau[i]);
      model[i] = m > 0.0 ? m : s2[i];
      edf[i] = mixed_edf(fit, curve[i]);
    }
  }
  if (!fit.ok) {
    t.arw_note = t.bias_instability_note = t.rrw_note =
        "sigma^2 = A/tau + F + C tau could not be fitted to " + std::to_string(n) + " taus";
    return t;
  }
  const auto clamp0 = [](double v) { return std::max(0.0, v); };

  // Angle random walk: A = part * tau, N = sqrt(A) / 60 ((deg/h) sqrt(s) = (1/60) deg/sqrt(h)).
  if (const auto r = read_term(NoiseKind::white, curve, fit, sub.cov, edf, t.arw_note)) {
    const double tau_r = curve[r->i].tau_s;
    const auto arw = [&](double part) { return std::sqrt(clamp0(part) * tau_r) / 60.0; };
    t.arw_deg_per_sqrt_h = estimate_of(*r, curve[r->i], arw(r->part), arw(r->lo), arw(r->hi));
  }
  // Rate random walk: C = part / tau, K = 60 sqrt(3 C) ((deg/h)/sqrt(s) = 60 (deg/h)/sqrt(h)).
  if (const auto r = read_term(NoiseKind::random_walk, curve, fit, sub.cov, edf, t.rrw_note)) {
    const double tau_r = curve[r->i].tau_s;
    const auto rrw = [&](double part) { return 60.0 * std::sqrt(3.0 * clamp0(part) / tau_r); };
    t.rrw_dph_per_sqrt_h = estimate_of(*r, curve[r->i], rrw(r->part), rrw(r->lo), rrw(r->hi));
  }
  // Bias instability: B = sqrt(F) / 0.664.
  std::string flicker_note;
  if (const auto r = read_term(NoiseKind::flicker, curve, fit, sub.cov, edf, flicker_note)) {
    const auto bi = [](double part) { return std::sqrt(std::max(0.0, part)) / kBiasInstabilityFactor; };
    t.bias_instability_dph = estimate_of(*r, curve[r->i], bi(r->part), bi(r->lo), bi(r->hi));
    return t;
  }
  // No flicker floor: where white noise meets a rate random walk the fitted curve has a V, and
  // its bottom bounds B from above (a floor under it would raise it). Read at the tau of the
  // fitted minimum, never the longest.
  if (!t.arw_deg_per_sqrt_h || !t.rrw_dph_per_sqrt_h) {
    if (!t.arw_deg_per_sqrt_h)
      t.bias_instability_note = "no white-noise region before a minimum (" + t.arw_note + ")";
    else
      t.bias_instability_note = "no minimum: sigma still falls at the longest tau, " + fmt(curve[n - 1].tau_s) +
                                " s (a longer record would show it); " + flicker_note;
    return t;
  }
  std::size_t i_min = 1;
  for (std::size_t i = 1; i + 1 < n; ++i)
    if (fit.total(tau[i]) < fit.total(tau[i_min])) i_min = i;
  const auto [lo, hi] = chi2_interval(s2[i_min], edf[i_min]);
  Reading r;
  r.i = i_min;
  r.edf = edf[i_min];
  r.share = fit.flicker / fit.total(tau[i_min]);
  t.bias_instability_dph = estimate_of(r, curve[i_min], curve[i_min].adev_dph / kBiasInstabilityFactor,
                                       std::sqrt(lo) / kBiasInstabilityFactor, std::sqrt(hi) / kBiasInstabilityFactor);
  t.bias_instability_note = flicker_note + ": sigma at the bottom of the V, " + fmt(curve[i_min].tau_s) +
                            " s, over 0.664 is an upper bound of the bias instability";
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
