// Benchmark of the run CSV: rows/s of read_csv_file (and of to_csv) for a day at 1 Hz
// (86,400 rows) and for 1,000,000 rows, on a file this program generates in /tmp.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <random>
#include <unistd.h>

#include "fogbench/storage/csv.hpp"

using namespace fogbench;
using Clock = std::chrono::steady_clock;

namespace {

// A plausible run: every column, values with full double precision (the worst case for
// parsing), a slow temperature ramp and gyro noise.
model::RunData make_run(std::size_t n) {
  std::mt19937_64 rng(42);
  std::normal_distribution<double> noise(0.0, 0.01);
  model::RunData run;
  for (std::size_t i = 0; i < n; ++i) {
    const double t = static_cast<double>(i);
    const double temp = 20.0 + 40.0 * std::sin(t / 20000.0);
    run.time_s.push_back(t);
    run.gyro_dph.push_back(0.05 * temp + noise(rng));
    run.t1_c.push_back(temp + noise(rng));
    run.t2_c.push_back(temp + 0.3 + noise(rng));
    run.setpoint_c.push_back(std::round(temp));
    run.chamber_c.push_back(temp + 1.0 + noise(rng));
    run.phase.push_back(i < 1800 ? model::Phase::settle : model::Phase::heating);
    run.step.push_back(static_cast<int>(i / 3600));
    run.flags.push_back(i % 1000 == 0 ? model::flag::frames_lost : 0);
  }
  return run;
}

double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

int bench(std::size_t rows, const std::filesystem::path& dir) {
  const auto path = dir / ("bench_" + std::to_string(rows) + ".csv");
  const model::RunData run = make_run(rows);

  auto w0 = Clock::now();
  const std::string text = storage::to_csv(run);
  const double to_csv_s = seconds_since(w0);
  if (auto ok = storage::write_csv_file(path, run); !ok) {
    std::fprintf(stderr, "%s\n", ok.error().message.c_str());
    return 1;
  }

  // Best of several: the first read also pays for the page cache.
  double best_s = 1e300;
  for (int rep = 0; rep < 5; ++rep) {
    auto t0 = Clock::now();
    auto r = storage::read_csv_file(path);
    const double s = seconds_since(t0);
    if (!r || r->size() != rows) {
      std::fprintf(stderr, "read failed: %s\n", r ? "wrong row count" : r.error().message.c_str());
      return 1;
    }
    best_s = std::min(best_s, s);
  }
  const double mb = static_cast<double>(text.size()) / 1e6;
  std::printf("csv_import rows=%zu size_mb=%.1f read_s=%.3f rows_per_s=%.0f mb_per_s=%.0f\n",
              rows, mb, best_s, static_cast<double>(rows) / best_s, mb / best_s);
  std::printf("csv_export rows=%zu to_csv_s=%.3f rows_per_s=%.0f\n", rows, to_csv_s,
              static_cast<double>(rows) / to_csv_s);
  std::filesystem::remove(path);
  return 0;
}

}  // namespace

int main() {
  const auto dir = std::filesystem::temp_directory_path() /
                   ("fogbench_bench_csv_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  int rc = bench(86'400, dir);
  if (rc == 0) rc = bench(1'000'000, dir);
  std::filesystem::remove_all(dir);
  return rc;
}
