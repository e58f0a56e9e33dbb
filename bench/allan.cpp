// Benchmark: overlapping Allan deviation of a 24 h run (86,400 one-second samples) and of a
// 10-day run (864,000) at every octave tau, plus the noise-term reading. A run of 262,144
// samples or more is done on two threads where there are two cores (model/src/allan.cpp,
// octaves_in_halves): both the wall time and the CPU of all threads are printed.
// Targets: 20 ms at 86,400 (issue 13); at 864,000 ten times faster than numpy's float64
// cumsum of the same definition (issue 30; bench/allan_numpy.py, run by `scripts/bench allan`
// on the same samples). Prints the median of 21 repetitions of wall and CPU time, and the figures read,
// so a wrong result shows beside a fast one.
//
// --write-dir DIR: also write each run's samples as raw little-endian float64 to
// DIR/allan<N>.f64, the numpy reference's input.
#include <algorithm>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <random>
#include <string>
#include <vector>

#include "fogbench/model/allan.hpp"

using namespace fogbench::model::allan;

namespace {
// The process's CPU (every thread's) or the monotonic clock, s.
double clock_s(clockid_t id) {
  timespec ts{};
  clock_gettime(id, &ts);
  return static_cast<double>(ts.tv_sec) + static_cast<double>(ts.tv_nsec) * 1e-9;
}

// White rate noise 0.15 deg/h per 1 s sample (ARW 0.0025 deg/sqrt(h)), a rate random walk of
// 0.001 deg/h per s (RRW 0.06 deg/h/sqrt(h)), on a 12.5 deg/h bias.
std::vector<double> make_run(int n) {
  std::mt19937_64 engine(1);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::vector<double> rate_dph(static_cast<std::size_t>(n));
  double walk_dph = 0.0;
  for (auto& r : rate_dph) {
    walk_dph += 0.001 * normal(engine);
    r = 12.5 + walk_dph + 0.15 * normal(engine);
  }
  return rate_dph;
}
}  // namespace

int main(int argc, char** argv) {
  std::string write_dir;
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--write-dir") == 0 && i + 1 < argc) {
      write_dir = argv[++i];
    } else {
      std::fprintf(stderr, "usage: bench_allan [--write-dir DIR]\n");
      return 2;
    }
  }
  for (const int n : {86400, 864000}) {
    const auto rate_dph = make_run(n);
    if (!write_dir.empty()) {
      const auto path = write_dir + "/allan" + std::to_string(n) + ".f64";
      std::FILE* f = std::fopen(path.c_str(), "wb");
      if (f == nullptr || std::fwrite(rate_dph.data(), sizeof(double), rate_dph.size(), f) != rate_dph.size()) {
        std::fprintf(stderr, "bench_allan: cannot write %s\n", path.c_str());
        return 1;
      }
      std::fclose(f);
    }
    const auto m = octave_cluster_sizes(rate_dph.size());
    std::vector<double> wall_ms, cpu_ms;
    NoiseTerms terms;
    std::vector<AdevPoint> curve;
    for (int rep = 0; rep < 21; ++rep) {
      const double w0 = clock_s(CLOCK_MONOTONIC), c0 = clock_s(CLOCK_PROCESS_CPUTIME_ID);
      curve = *overlapping_adev(rate_dph, 1.0, m);
      terms = noise_terms(curve);
      cpu_ms.push_back((clock_s(CLOCK_PROCESS_CPUTIME_ID) - c0) * 1e3);
      wall_ms.push_back((clock_s(CLOCK_MONOTONIC) - w0) * 1e3);
    }
    std::sort(wall_ms.begin(), wall_ms.end());
    std::sort(cpu_ms.begin(), cpu_ms.end());
    std::printf("overlapping ADEV of %d samples at %zu octave taus + noise terms: median %.2f ms wall "
                "(min %.2f, max %.2f), %.2f ms CPU of all threads\n",
                n, m.size(), wall_ms[wall_ms.size() / 2], wall_ms.front(), wall_ms.back(), cpu_ms[cpu_ms.size() / 2]);
    std::printf("  adev(1 s) %.12g deg/h, adev(%.0f s) %.12g deg/h; ARW %.5f deg/sqrt(h) (given 0.0025), "
                "RRW %.4f deg/h/sqrt(h) (given 0.06)\n",
                curve.front().adev_dph, curve.back().tau_s, curve.back().adev_dph,
                terms.arw_deg_per_sqrt_h ? terms.arw_deg_per_sqrt_h->value : -1.0,
                terms.rrw_dph_per_sqrt_h ? terms.rrw_dph_per_sqrt_h->value : -1.0);
  }
  return 0;
}
