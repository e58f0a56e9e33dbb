// Benchmark: model::sf::fit of a 10-plateau rate sequence (issue 29: under 50 ms). Each
// plateau (-40 .. 70 degC) runs 13 rates (0, +-1, +-10, +-50, +-100, +-200, +-400 deg/s) for 60 s
// each, sampled at 1 Hz (7,800 samples, this project's gyros) and at 100 Hz (780,000 samples, a
// gyro read at its full rate), with white noise and a 15 ppm/degC scale factor. Prints the
// median of 21 repetitions of CPU time, and the figures read, so a wrong result shows beside a
// fast one.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <random>
#include <vector>

#include "fogbench/model/scale_factor.hpp"

namespace sf = fogbench::model::sf;

namespace {
double cpu_s() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + static_cast<double>(ts.tv_nsec) * 1e-9;
}

sf::RateRecord make(int hz) {
  std::mt19937_64 engine(1);
  std::normal_distribution<double> normal(0.0, 1.0);
  const double rates[] = {0, 1, -1, 10, -10, 50, -50, 100, -100, 200, -200, 400, -400};
  sf::RateRecord r;
  double t = 0.0;
  const double dt = 1.0 / hz;
  for (int p = 0; p < 10; ++p) {
    const double temp_c = -40.0 + 110.0 * p / 9.0;
    const double scale = 1.0 + 15e-6 * (temp_c - 20.0);
    for (double rate : rates)
      for (int k = 0; k < 60 * hz; ++k, t += dt) {
        r.time_s.push_back(t);
        r.plateau.push_back(p);
        r.rate_in_dps.push_back(rate);
        r.coil_c.push_back(temp_c + 0.005 * normal(engine));
        // 0.146 deg/h white per 1 s sample, sqrt(hz) times that per sample at hz
        r.rate_out_dps.push_back(0.002 + scale * rate + 0.146 / 3600.0 * std::sqrt(static_cast<double>(hz)) * normal(engine));
      }
  }
  return r;
}
}  // namespace

int main() {
  for (int hz : {1, 100}) {
    const auto rec = make(hz);
    std::vector<double> times;
    sf::Result last;
    for (int rep = 0; rep < 21; ++rep) {
      const double t0 = cpu_s();
      auto res = sf::fit(rec);
      times.push_back(cpu_s() - t0);
      if (!res) {
        std::fprintf(stderr, "fit failed: %s\n", res.error().c_str());
        return 1;
      }
      last = *res;
    }
    std::nth_element(times.begin(), times.begin() + 10, times.end());
    std::printf("%d Hz, %zu samples, 10 plateaus: median %.3f ms CPU; TC %.4f +- %.4f ppm/degC (true 15), NL of plateau 0 %.3f ppm\n", hz,
                rec.size(), 1e3 * times[10], last.tc_ppm_per_c.value.value_or(-1), last.tc_ppm_per_c.se, last.plateaus[0].nonlinearity_ppm);
  }
}
