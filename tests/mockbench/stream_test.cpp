// The streaming gyro without I/O (sim/mock/frames.hpp): the 1 s means of its frames carry the
// AR noise it was given whatever the phase of the reader's window, the power windows start and
// stop its frames, a warm-up follows each power-on, and the quantiser loses nothing.
#include <catch2/catch.hpp>

#include <cmath>
#include <numeric>
#include <random>
#include <vector>

#include "fogbench/model/stats.hpp"
#include "frames.hpp"

using namespace fogbench;
using namespace fogbench::mock;

namespace {

// The paper's noise, the defaults of sim::GyroTruth.
constexpr double k1 = -0.005, k2 = -0.04, sigma_a_dph = 0.146, mu0_dph = -8.097;

StreamParams paper_noise(int n, double counts_per_dph) {
  StreamParams p;
  p.frame_rate_hz = n;
  p.counts_per_dph = counts_per_dph;
  p.ar = {k1, k2};
  p.sigma_a_dph = sigma_a_dph;
  return p;  // no outliers: a 2.5 deg/h spike in 4000 s would add 7% to the variance
}

// Streams `seconds` seconds and averages the frames as the daemon does (the mean of the counts
// of the frames in each window, times the scale), the window boundaries at (k + phase) * N
// frames, each moved by up to +-jitter frames (a reader's timer is late or early).
std::vector<double> daemon_means(GyroStream& g, int n, double counts_per_dph, int seconds, double phase, int jitter,
                                 std::mt19937_64& rng) {
  std::vector<std::int64_t> counts;
  std::vector<StreamFrame> frames;
  std::mt19937_64 stream_rng(99);
  for (int s = 0; s < seconds; ++s) {
    g.second(s, mu0_dph, PowerWindow{}, stream_rng, frames);
    for (const auto& f : frames) counts.push_back(f.counts);
  }
  std::uniform_int_distribution<int> move(-jitter, jitter);
  std::vector<std::size_t> bounds;
  for (int k = 1; k < seconds - 1; ++k) {
    bounds.push_back(static_cast<std::size_t>(std::lround((k + phase) * n) + move(rng)));
  }
  std::vector<double> means;
  for (std::size_t i = 0; i + 1 < bounds.size(); ++i) {
    const auto sum = std::accumulate(counts.begin() + static_cast<std::ptrdiff_t>(bounds[i]),
                                     counts.begin() + static_cast<std::ptrdiff_t>(bounds[i + 1]), std::int64_t{0});
    means.push_back(static_cast<double>(sum) / static_cast<double>(bounds[i + 1] - bounds[i]) / counts_per_dph);
  }
  return means;
}

}  // namespace

TEST_CASE("a streaming gyro's 1 s means carry the AR(2) noise it was given, whatever the window's phase") {
  // 4000 s of 100 frames. Least-squares AR(2) on n = 4000 samples: the standard error of k1 and
  // k2 is sqrt((1 - k2^2) / n) = 0.0158, of sigma_a about sigma_a / sqrt(2n) = 0.0016 deg/h.
  // Four standard errors each. Before the gyro streamed (each simulated second's 1 s value
  // spread over its frames), a window at phase 0.37 averaged 63% of one second with 37% of the
  // next: std sqrt(0.63^2 + 0.37^2) * 0.146 = 0.107 deg/h and a lag-1 correlation of
  // 0.63 * 0.37 / 0.534 = 0.44, so a fitted k1 near +0.4: 25 standard errors off both.
  // A jitter of +-5 frames changes each window's length by up to 10%: its noise variance goes
  // as N/length, 1 + 2 * 8.3/100^2 on average, +0.1% of sigma_a, far inside the tolerance.
  constexpr int n = 100, seconds = 4000;
  const double se_k = std::sqrt((1 - k2 * k2) / seconds);
  const double se_sigma = sigma_a_dph / std::sqrt(2.0 * seconds);
  // Rate mode, 1e-4 deg/h per count; increment mode of the example's odd units, 2.88 deg/h per
  // count and frame: its quantisation error per window is under one count over 100 frames,
  // 0.029 deg/h uniform, which adds 0.0005 deg/h to sigma_a (a third of its standard error).
  for (double counts_per_dph : {1e4, 1.0 / 2.88}) {
    for (double phase : {0.0, 0.37, 0.5}) {
      for (int jitter : {0, 5}) {
        INFO("counts per deg/h " << counts_per_dph << ", phase " << phase << ", jitter +-" << jitter << " frames");
        GyroStream g(paper_noise(n, counts_per_dph));
        std::mt19937_64 rng(1);
        auto y = daemon_means(g, n, counts_per_dph, seconds, phase, jitter, rng);
        const double mean = std::accumulate(y.begin(), y.end(), 0.0) / static_cast<double>(y.size());
        // The mean is mu0: the noise's std over 4000 samples is 0.0023 deg/h.
        CHECK(mean == Approx(mu0_dph).margin(0.01));
        for (auto& v : y) v -= mean;
        auto fit = model::fit_ar(y, 2);
        REQUIRE(fit.has_value());
        CHECK(fit->k[0] == Approx(k1).margin(4 * se_k));
        CHECK(fit->k[1] == Approx(k2).margin(4 * se_k));
        CHECK(std::sqrt(fit->sigma_a2) == Approx(sigma_a_dph).margin(4 * se_sigma));
      }
    }
  }
}

TEST_CASE("a streaming gyro with another AR: the fit finds its k1, not the frames' smoothing") {
  // k1 = 0.6, k2 = -0.2 (a clearly coloured noise) at 10 frames a second, windows of exactly N
  // frames at phase 0.5 (as a paced daemon's are): the same four standard errors as above
  // (sqrt((1 - 0.04)/4000) = 0.0155). The frames' correlation is at whole seconds only, so a
  // window that is a frame short or long pairs some frames with the wrong second: with windows
  // jittered by +-1 of 10 frames the fitted k1 falls to about 0.47 (measured). The paper's
  // noise (k1, k2 near 0) does not care, as the test above shows with +-5 of 100.
  StreamParams p;
  p.frame_rate_hz = 10;
  p.counts_per_dph = 1e4;
  p.ar = {0.6, -0.2};
  p.sigma_a_dph = 0.3;
  GyroStream g(p);
  std::mt19937_64 rng(3);
  auto y = daemon_means(g, 10, 1e4, 4000, 0.5, 0, rng);
  const double mean = std::accumulate(y.begin(), y.end(), 0.0) / static_cast<double>(y.size());
  for (auto& v : y) v -= mean;
  auto fit = model::fit_ar(y, 2);
  REQUIRE(fit.has_value());
  CHECK(fit->k[0] == Approx(0.6).margin(0.062));
  CHECK(fit->k[1] == Approx(-0.2).margin(0.062));
  CHECK(std::sqrt(fit->sigma_a2) == Approx(0.3).margin(4 * 0.3 / std::sqrt(8000.0)));
}

TEST_CASE("the quantiser carries its remainder: any N consecutive frames sum to their value within a count") {
  // Increment mode, 2.88 deg/h per count: -8.097 deg/h is -2.811 counts a frame, so 100 frames
  // sum to -281.1 counts: -281 or -282 for every window, whatever its start.
  StreamParams p;
  p.frame_rate_hz = 100;
  p.counts_per_dph = 1.0 / 2.88;
  p.sigma_a_dph = 0;
  GyroStream g(p);
  std::mt19937_64 rng(5);
  std::vector<std::int64_t> counts;
  std::vector<StreamFrame> frames;
  for (int s = 0; s < 5; ++s) {
    g.second(s, mu0_dph, PowerWindow{}, rng, frames);
    REQUIRE(frames.size() == 100);
    for (const auto& f : frames) {
      CHECK(f.powered);
      CHECK((f.counts == -3 || f.counts == -2));
      counts.push_back(f.counts);
    }
  }
  for (std::size_t start = 0; start + 100 <= counts.size(); start += 7) {
    const auto sum = std::accumulate(counts.begin() + static_cast<std::ptrdiff_t>(start),
                                     counts.begin() + static_cast<std::ptrdiff_t>(start + 100), std::int64_t{0});
    CHECK(std::abs(static_cast<double>(sum) - 100 * mu0_dph / 2.88) < 1.0);
  }
  // The sequence counter runs on across seconds: 500 frames, 500 mod 256 = 244 next.
  CHECK(frames.back().sequence == 243);
}

TEST_CASE("power: no frames while unpowered, the counter from 0 and warming_up for 1 s at power-on, and the warm-up decays from there") {
  // No noise, so every value is exact: rate mode at 1e-4 deg/h per count, 10 frames a second,
  // warm-up 5 deg/h with tau 20 s. The unit is off from 3 s to 7.5 s.
  StreamParams p;
  p.frame_rate_hz = 10;
  p.counts_per_dph = 1e4;
  p.sigma_a_dph = 0;
  p.warmup_dph = 5;
  p.warmup_tau_s = 20;
  GyroStream g(p);
  std::mt19937_64 rng(7);
  const PowerWindow off{3.0, 7.5};
  std::vector<StreamFrame> frames;
  std::vector<double> times_s;
  std::vector<StreamFrame> all;
  for (int s = 0; s < 40; ++s) {
    g.second(s, mu0_dph, off, rng, frames);
    for (int j = 0; j < 10; ++j) {
      times_s.push_back(s + j / 10.0);
      all.push_back(frames[static_cast<std::size_t>(j)]);
    }
    if (s < 3) CHECK(g.powered_on_at_s() == 0.0);  // powered with the bench at 0
  }
  CHECK(g.powered());
  CHECK(g.powered_on_at_s() == 7.5);
  for (std::size_t i = 0; i < all.size(); ++i) {
    const double t = times_s[i];
    INFO("t = " << t << " s");
    CHECK(all[i].powered == (t < 3.0 || t >= 7.5));
    if (!all[i].powered) continue;
    // Each frame: mu0 + 5 exp(-(t - t_on)/20), to a count (1e-4 deg/h).
    const double t_on = t < 3.0 ? 0.0 : 7.5;
    const double expect_dph = mu0_dph + 5.0 * std::exp(-(t - t_on) / 20.0);
    CHECK(all[i].counts * 1e-4 == Approx(expect_dph).margin(1e-4));
    // The start-up the gyro announces: `warming_up` for the first second of each power-on.
    CHECK(all[i].warming_up == (t - t_on < 1.0));
  }
  // The counter: 0..29 before the cut, 0 again at 7.5 s (frame 75).
  CHECK(all[29].sequence == 29);
  CHECK(all[75].sequence == 0);
  CHECK(all[76].sequence == 1);
  // The last second's mean, for the status: frames at 39.0..39.9 s, 31.5..32.4 s after power-on.
  double expect = 0;
  for (int j = 0; j < 10; ++j) expect += mu0_dph + 5.0 * std::exp(-(39.0 + j / 10.0 - 7.5) / 20.0);
  CHECK(g.last_mean_dph() == Approx(expect / 10).margin(1e-9));
}
