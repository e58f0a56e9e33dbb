// Benchmark of the two fits on long simulated runs (issue 2's speed figures): the `paper` fit
// (shared lag over 0..600 s) and the `joint` fit of d(T1)@auto + grad@auto (a lag per term),
// best of several repetitions on one core, for N from 6,000 to 864,000 samples.
// Usage: bench_fit [--reps R] [--sizes 6000,86400] [--csv-dir DIR]  (DIR: write each run's CSV
// there, for bench/fit_numpy.py and the whole-process comparison in scripts/bench).
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "fogbench/model/model.hpp"
#include "cycling.hpp"
#include "fogbench/sim/sim.hpp"
#include "fogbench/storage/csv.hpp"

using namespace fogbench;

namespace {

double best_ms(const model::RunData& run, const model::TermList& terms, const model::FitOptions& o, int reps,
               std::string* summary) {
  double best = 1e300;
  for (int r = 0; r < reps; ++r) {
    const auto t0 = std::chrono::steady_clock::now();
    auto m = model::fit(run, terms, o);
    const auto t1 = std::chrono::steady_clock::now();
    if (!m) {
      std::fprintf(stderr, "fit failed: %s\n", m.error().message.c_str());
      std::exit(1);
    }
    best = std::min(best, std::chrono::duration<double, std::milli>(t1 - t0).count());
    *summary = m->terms_string();
  }
  return best;
}

}  // namespace

int main(int argc, char** argv) {
  int reps = 7;
  std::vector<std::size_t> sizes = {6000, 21600, 86400, 345600, 864000};
  std::string csv_dir;
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--reps") && i + 1 < argc) reps = std::atoi(argv[++i]);
    else if (!std::strcmp(argv[i], "--csv-dir") && i + 1 < argc) csv_dir = argv[++i];
    else if (!std::strcmp(argv[i], "--sizes") && i + 1 < argc) {
      sizes.clear();
      for (char* s = std::strtok(argv[++i], ","); s; s = std::strtok(nullptr, ",")) sizes.push_back(std::strtoul(s, nullptr, 10));
    } else {
      std::fprintf(stderr, "usage: bench_fit [--reps R] [--sizes N,N,...] [--csv-dir DIR]\n");
      return 2;
    }
  }
  const auto paper = *model::parse_terms("paper");
  const auto joint_terms = *model::parse_terms("d(T1)@auto + grad@auto");
  model::FitOptions po, jo;
  jo.method = model::Method::joint;
  std::printf("%10s %12s %12s  %s\n", "N", "paper_ms", "joint_ms", "joint lags");
  for (std::size_t n : sizes) {
    sim::SimConfig cfg;
    cfg.seed = 5;
    auto runs = sim::simulate(cfg, bench::cycling_program(n));
    if (!runs) {
      std::fprintf(stderr, "simulation failed: %s\n", runs.error().c_str());
      return 1;
    }
    model::RunData& run = runs->front();
    run.name = "bench-" + std::to_string(n);
    if (!csv_dir.empty()) {
      if (auto w = storage::write_csv_file(csv_dir + "/run" + std::to_string(n) + ".csv", run); !w) {
        std::fprintf(stderr, "%s\n", w.error().message.c_str());
        return 1;
      }
    }
    std::string s1, s2;
    const double p_ms = best_ms(run, paper, po, reps, &s1);
    const double j_ms = best_ms(run, joint_terms, jo, reps, &s2);
    std::printf("%10zu %12.2f %12.2f  %s\n", n, p_ms, j_ms, s2.c_str());
    std::fflush(stdout);
  }
  return 0;
}
