// Benchmark: one sample of the firmware form of a model (model::firmware::Compensator::step),
// the cost that online compensation adds per unit and second. Target (issue 13): under 1 us.
// The model has the paper's two terms plus a filter and a product (two 61-sample slopes).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <vector>

#include "fogbench/model/firmware.hpp"

using namespace fogbench::model;

namespace {
double cpu_s() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + static_cast<double>(ts.tv_nsec) * 1e-9;
}
}  // namespace

int main() {
  Model m;
  m.mu0_dph = -8.0;
  for (const char* text : {"d(T1)@40", "grad@40", "lp(T1,600)", "T1*d(T1)@35"}) {
    auto t = parse_term(text);
    FittedTerm f;
    f.term = *t;
    f.coef = 0.5;
    m.terms.push_back(f);
  }
  auto p = firmware::compile(m);
  if (!p) {
    std::fprintf(stderr, "%s\n", p.error().c_str());
    return 1;
  }
  constexpr int n = 1'000'000;
  std::vector<double> per_step_ns;
  double sink = 0.0;
  for (int rep = 0; rep < 5; ++rep) {
    firmware::Compensator c(*p);
    const double t0 = cpu_s();
    for (int i = 0; i < n; ++i) {
      const double t1 = 20.0 + 10.0 * std::sin(i * 1e-3);
      sink += c.step({t1, t1 - 0.3, t1, static_cast<double>(i)});
    }
    per_step_ns.push_back((cpu_s() - t0) / n * 1e9);
  }
  std::sort(per_step_ns.begin(), per_step_ns.end());
  std::printf("firmware program of %zu operations, %d samples of history: %.0f ns per unit-second "
              "(median of 5 x %d steps; target 1000 ns) [%g]\n",
              p->ops.size(), p->ring_size, per_step_ns[2], n, sink != 0.0 ? 1.0 : 0.0);
  return 0;
}
