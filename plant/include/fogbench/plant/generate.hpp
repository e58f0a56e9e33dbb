// A plant's worth of runs for measuring and testing the fleet queries (issue 14, point 5):
// runs of N units on several benches, each unit's model coefficients and verdict figures drawn
// per lot, one lot shifted and a few outlier units planted, and every run's samples (or those of
// the first N runs, for quick use), streamed a run at a time with COPY so memory stays flat.
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "fogbench/plant/plant.hpp"

namespace fogbench::plant {

struct GenerateOptions {
  int runs = 10000;
  int units_per_run = 2;
  int lots = 20;            // lot k holds the units of runs [k * runs / lots, (k + 1) * runs / lots)
  int benches = 4;          // runs go to benches in turn
  int shifted_lot = 13;     // this lot's `figure` mean is shifted by shift_sigma
  double shift_sigma = 1.0;
  int outliers = 5;         // units whose `figure` is outlier_sigma away, outside the shifted lot
  double outlier_sigma = 6.0;
  std::string figure = "d(T1)";  // the figure shifted and planted
  // Each unit's verdict, drawn independently of its figures (they exercise the p-charts):
  // fail with fail_rate, marginal with marginal_rate, else pass; the bench marginal_bench
  // (1-based, 0: none) gives marginal with marginal_bench_rate from run marginal_from_run on.
  double fail_rate = 0.01, marginal_rate = 0.05;
  int marginal_bench = 0;
  double marginal_bench_rate = 0.20;
  int marginal_from_run = 0;
  std::optional<int> sample_runs;  // the first runs that also get samples (unset: every run) ...
  int samples_per_unit = 10000;    // ... this many per unit (1 s apart)
  int samples_commit_runs = 100;   // the samples are committed every this many runs
  // Called after each run's samples are copied (from the generating thread).
  std::function<void(std::int64_t runs_done, std::int64_t runs_total, std::int64_t samples)> progress;
  std::uint64_t seed = 1;
  std::string bench_prefix = "gen-bench-";
};

struct GeneratedPlant {
  std::string shifted_lot;
  std::string marginal_bench;  // the bench with extra marginal verdicts ("" when none)
  std::vector<std::string> outlier_serials;
  std::int64_t runs = 0, units = 0, figures = 0, samples = 0;
};

// Replaces what the plant held for the generated benches (bench ids starting with
// bench_prefix): the old plant is deleted and the run-level records (runs, units, models,
// verifications, figures) written in one transaction; then the samples, one COPY per run, in
// key order (bench, run), committed every samples_commit_runs runs. A generation interrupted
// while it writes samples leaves every run-level record and the samples of the runs committed
// (the statistics read only the run-level records). Every figure but the planted ones is drawn from a normal
// distribution truncated at 2.5 sigma (the units a plant's incoming inspection lets through):
// no natural value lies beyond the 3-sigma limits, so a flag means a planted unit.
PlantResult<GeneratedPlant> generate_fleet(Connection& c, const GenerateOptions& o);

}  // namespace fogbench::plant
