// Allan figures as acceptance evidence: the 1-sigma intervals of ARW, bias instability and RRW
// must hold the true figure about 68 % of the time, scored on records generated with known white,
// flicker and random-walk rate noise, and the figures must be read wherever they are visible.
#include <catch2/catch.hpp>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "fogbench/model/allan.hpp"

using namespace fogbench::model::allan;

namespace {

// Box-Muller on a fixed engine, both outputs used: the same series with every standard library.
struct Normal {
  std::mt19937_64 engine;
  bool has_spare = false;
  double spare = 0.0;
  explicit Normal(std::uint64_t seed) : engine(seed) {}
  double operator()() {
    if (has_spare) {
      has_spare = false;
      return spare;
    }
    constexpr double two_pi = 6.283185307179586;
    const double u1 = (static_cast<double>(engine() >> 11) + 0.5) * 0x1.0p-53;
    const double u2 = static_cast<double>(engine() >> 11) * 0x1.0p-53;
    const double r = std::sqrt(-2.0 * std::log(u1));
    spare = r * std::sin(two_pi * u2);
    has_spare = true;
    return r * std::cos(two_pi * u2);
  }
};

// Flicker rate noise as a sum of first-order Gauss-Markov (AR(1)) processes whose correlation
// times are spaced an octave apart, 0.5 s .. 8 record lengths, each of the same variance: their
// Lorentzian spectra add to 1/f between the extreme corners, so sigma^2(tau) is flat in between.
// Its exact Allan variance is computed from the autocovariance R(k) = v a^k (a = exp(-1/T)) of
// each process: with S the sum of m consecutive samples and S' the next m,
//   AVAR(m) = (Var S - Cov(S, S')) / m^2,  Var S = sum_{|k|<m} (m-|k|) R(k),
//   Cov(S, S') = sum_{|d|<m} (m-|d|) R(m+d).
struct Flicker {
  std::vector<double> a, drive;  // AR coefficient and innovation std per process
  double v = 0.0;                // each process's variance, (deg/h)^2

  Flicker(std::size_t n_samples, double floor_avar) {
    std::vector<double> t_s;
    for (double t = 0.5; t <= 8.0 * static_cast<double>(n_samples); t *= 2.0) t_s.push_back(t);
    for (const double t : t_s) a.push_back(std::exp(-1.0 / t));
    v = 1.0;
    // Scale so that the exact AVAR at 512 s (mid-record) is the requested floor.
    v = floor_avar / avar(512);
    for (const double ai : a) drive.push_back(std::sqrt(v * (1.0 - ai * ai)));
  }
  double avar(std::int64_t m) const {
    double sum = 0.0;
    const auto md = static_cast<double>(m);
    for (const double ai : a) {
      double var_s = md, cov = 0.0, pk = 1.0;  // pk = a^k
      for (std::int64_t k = 1; k < m; ++k) {
        pk *= ai;
        var_s += 2.0 * (md - static_cast<double>(k)) * pk;
      }
      // Cov: R(m+d) for d = -(m-1)..m-1, a^(m-|d|)... written as sum over j = m+d = 1..2m-1 of
      // (m - |j - m|) a^j.
      double pj = 1.0;
      for (std::int64_t j = 1; j < 2 * m; ++j) {
        pj *= ai;
        cov += (md - std::abs(static_cast<double>(j - m))) * pj;
      }
      sum += v * (var_s - cov) / (md * md);
    }
    return sum;
  }
};

// One record: white rate noise of std s_w per 1 s sample (A = s_w^2 (deg/h)^2 s), the flicker
// above, and a rate random walk of step std q per second. The walk's exact AVAR is
// q^2 (m/3 + 1/(6m)) (sum of the squared weights of each step in S' - S, over 2 m^2): C = q^2/3
// (deg/h)^2/s and a white-like q^2/6, counted in A.
std::vector<double> record(std::uint64_t seed, std::size_t n, double s_w, const Flicker& fl, double q) {
  Normal g(seed);
  std::vector<double> x(fl.a.size());
  for (auto& xi : x) xi = std::sqrt(fl.v) * g();  // each process starts stationary
  std::vector<double> rate(n);
  double walk = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    double f = 0.0;
    for (std::size_t j = 0; j < x.size(); ++j) {
      x[j] = fl.a[j] * x[j] + fl.drive[j] * g();
      f += x[j];
    }
    walk += q * g();
    rate[i] = s_w * g() + f + walk;
  }
  return rate;
}

bool inside(const NoiseEstimate& e, double truth) { return e.ci_low <= truth && truth <= e.ci_high; }

}  // namespace

TEST_CASE("Allan figures: each inside its 1-sigma interval on 60-76 of 100 generated records",
          "[allan][allan_ci]") {
  // 2^17 samples at 1 s (36 h): octave taus 1..32768 s. White s_w = 1 deg/h (A = 1), flicker
  // floor F = 2e-3 (deg/h)^2 (B = sqrt(F)/0.664 = 0.0673 deg/h), walk C = q^2/3 = 2.44e-7
  // (deg/h)^2/s (K = 60 sqrt(3 C) = 0.0513 deg/h/sqrt(h)): white meets the floor at 500 s and the
  // walk at 8192 s, so every term is at least half of sigma^2 over an octave or more.
  constexpr std::size_t n = std::size_t{1} << 17;
  constexpr double s_w = 0.5, floor_avar = 2e-3, c_walk = 4.88e-7;
  const double q = std::sqrt(3.0 * c_walk);
  const Flicker fl(n, floor_avar);
  const auto sizes = octave_cluster_sizes(n);
  // The generated flicker is flat within 5 % from 16 s to the last tau but one (its AVAR is
  // 1.18 F at 1 s: the 0.5 s process is nearly white).
  std::vector<double> flicker_avar;
  for (const auto m : sizes) flicker_avar.push_back(fl.avar(m));
  for (std::size_t i = 4; i + 1 < sizes.size(); ++i) {
    INFO("m = " << sizes[i]);
    CHECK(flicker_avar[i] == Approx(floor_avar).epsilon(0.05));
  }

  // True figures: N = sqrt(s_w^2 + q^2/6) / 60; K = 60 sqrt(3 C); B from the generated flicker's
  // exact AVAR at the tau it is read at (flat within the few per cent checked above).
  const double arw_true = std::sqrt(s_w * s_w + q * q / 6.0) / 60.0, rrw_true = 60.0 * std::sqrt(3.0 * c_walk);
  int arw_in = 0, bi_in = 0, rrw_in = 0, arw_read = 0, bi_read = 0, rrw_read = 0;
  int arw_seen = 0, bi_seen = 0, rrw_seen = 0;
  constexpr int records = 100;
  for (int r = 0; r < records; ++r) {
    const auto rate = record(1000 + static_cast<std::uint64_t>(r), n, s_w, fl, q);
    const auto curve = overlapping_adev(rate, 1.0, sizes);
    REQUIRE(curve);
    const auto t = noise_terms(*curve);
    REQUIRE(t.fit.ok);
    const double last_tau = curve->back().tau_s;
    // Visible, as the header defines it: share >= 1/2 at a tau before the longest and the fitted
    // part over 2 standard errors.
    auto visible = [&](NoiseKind k, double param, double se) {
      bool share = false;
      for (std::size_t i = 0; i + 1 < curve->size(); ++i)
        share = share || t.fit.part(k, (*curve)[i].tau_s) >= 0.5 * t.fit.total((*curve)[i].tau_s);
      return share && param > 2.0 * se;
    };
    const bool arw_vis = visible(NoiseKind::white, t.fit.white, t.fit.white_se);
    const bool bi_vis = visible(NoiseKind::flicker, t.fit.flicker, t.fit.flicker_se);
    const bool rrw_vis = visible(NoiseKind::random_walk, t.fit.walk, t.fit.walk_se);
    arw_seen += arw_vis, bi_seen += bi_vis, rrw_seen += rrw_vis;
    INFO("record " << r << ": " << t.arw_note << " | " << t.bias_instability_note << " | " << t.rrw_note);
    CHECK(arw_vis == t.arw_deg_per_sqrt_h.has_value());
    CHECK(rrw_vis == t.rrw_dph_per_sqrt_h.has_value());
    // A bias instability is read whenever the floor is visible (an upper bound may stand when not).
    if (bi_vis) CHECK((t.bias_instability_dph && t.bias_instability_note.empty()));
    if (t.arw_deg_per_sqrt_h) {
      ++arw_read;
      arw_in += inside(*t.arw_deg_per_sqrt_h, arw_true);
    }
    if (t.bias_instability_dph && bi_vis) {
      const auto& b = *t.bias_instability_dph;
      // Never the longest, noisiest tau.
      CHECK(b.from_tau_s < last_tau);
      std::size_t i = 0;
      while ((*curve)[i].tau_s != b.from_tau_s) ++i;
      ++bi_read;
      bi_in += inside(b, std::sqrt(flicker_avar[i]) / 0.664);
    }
    if (t.rrw_dph_per_sqrt_h) {
      CHECK(t.rrw_dph_per_sqrt_h->from_tau_s < last_tau);
      ++rrw_read;
      rrw_in += inside(*t.rrw_dph_per_sqrt_h, rrw_true);
    }
  }
  INFO("inside / read / visible: ARW " << arw_in << "/" << arw_read << "/" << arw_seen << ", B " << bi_in << "/"
       << bi_read << "/" << bi_seen << ", RRW " << rrw_in << "/" << rrw_read << "/" << rrw_seen);
  // Every term visible on (nearly) every record, so that the scores below count ~100 records.
  CHECK(arw_seen == records);
  CHECK(bi_seen >= 95);
  CHECK(rrw_seen >= 95);
  // A calibrated 1-sigma interval holds the truth with p = 0.6827: over ~100 independent records
  // the count inside is binomial, mean 68.3, std sqrt(100 p (1-p)) = 4.65. The accepted band,
  // 60..76 % (the issue's), is 68.3 -+ 1.7 std: a calibrated interval passes it with
  // probability ~0.93 per figure, while intervals too narrow or too wide by a third (coverage
  // ~50 % or ~82 %) fail it most of the time. The seeds are fixed, so the outcome is the same on every run.
  auto pct = [](int in, int read) { return read > 0 ? 100.0 * in / read : 0.0; };
  CHECK(pct(arw_in, arw_read) >= 60.0);
  CHECK(pct(arw_in, arw_read) <= 76.0);
  CHECK(pct(bi_in, bi_read) >= 60.0);
  CHECK(pct(bi_in, bi_read) <= 76.0);
  CHECK(pct(rrw_in, rrw_read) >= 60.0);
  CHECK(pct(rrw_in, rrw_read) <= 76.0);
}

TEST_CASE("Allan figures on 20 clean 55 h records: bias instability and RRW read on every one",
          "[allan][allan_ci]") {
  // 55 h = 198,000 samples: octave taus up to 65,536 s, whose longest has about 2 degrees of
  // freedom. The same mix as above; both terms are visible on each record and must be read,
  // never at the longest tau.
  constexpr std::size_t n = 198000;
  const Flicker fl(n, 2e-3);
  const auto sizes = octave_cluster_sizes(n);
  for (int r = 0; r < 20; ++r) {
    const auto rate = record(5000 + static_cast<std::uint64_t>(r), n, 0.5, fl, std::sqrt(3.0 * 4.88e-7));
    const auto curve = overlapping_adev(rate, 1.0, sizes);
    REQUIRE(curve);
    const auto t = noise_terms(*curve);
    INFO("record " << r << ": " << t.bias_instability_note << " | " << t.rrw_note);
    REQUIRE(t.bias_instability_dph);
    REQUIRE(t.rrw_dph_per_sqrt_h);
    CHECK(t.bias_instability_note.empty());
    CHECK(t.bias_instability_dph->from_tau_s < curve->back().tau_s);
    CHECK(t.rrw_dph_per_sqrt_h->from_tau_s < curve->back().tau_s);
  }
}

TEST_CASE("flicker-dominated records all read a bias instability", "[allan][allan_ci]") {
  // White s_w = 0.1 deg/h per 1 s sample (A = 0.01) under a floor F = 2e-3 (deg/h)^2: the floor
  // is over half of sigma^2 from 5 s on, to the end of the record, and there is no walk. The
  // floor must be read (not as an upper bound) on each of 10 records, never at the longest tau.
  constexpr std::size_t n = std::size_t{1} << 16;
  const Flicker fl(n, 2e-3);
  const auto sizes = octave_cluster_sizes(n);
  for (int r = 0; r < 10; ++r) {
    const auto rate = record(7000 + static_cast<std::uint64_t>(r), n, 0.1, fl, 0.0);
    const auto curve = overlapping_adev(rate, 1.0, sizes);
    REQUIRE(curve);
    const auto t = noise_terms(*curve);
    INFO("record " << r << ": " << t.bias_instability_note);
    REQUIRE(t.bias_instability_dph);
    CHECK(t.bias_instability_note.empty());
    CHECK(t.bias_instability_dph->from_tau_s < curve->back().tau_s);
    CHECK(t.bias_instability_dph->value == Approx(std::sqrt(2e-3) / 0.664).epsilon(0.3));
  }
}
