// Benchmark of the SQLite store: samples stored per second by import_run (86,400 and
// 1,000,000 rows into a fresh file) and by append_samples at the daemon's pace (8 rows per
// call: one second of 8 units), with synchronous=FULL (the default) and NORMAL.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <unistd.h>
#include <vector>

#include "fogbench/storage/runs.hpp"
#include "fogbench/storage/samples.hpp"
#include "fogbench/storage/store.hpp"

using namespace fogbench;
using namespace fogbench::storage;
using Clock = std::chrono::steady_clock;

namespace {

double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

model::RunData make_run(std::size_t n) {
  model::RunData run;
  run.name = "bench";
  for (std::size_t i = 0; i < n; ++i) {
    const double t = static_cast<double>(i);
    const double temp = 20.0 + 40.0 * std::sin(t / 20000.0);
    run.time_s.push_back(t);
    run.gyro_dph.push_back(0.05 * temp + 1e-3 * std::sin(t));
    run.t1_c.push_back(temp);
    run.t2_c.push_back(temp + 0.3);
    run.setpoint_c.push_back(std::round(temp));
    run.chamber_c.push_back(temp + 1.0);
    run.phase.push_back(i < 1800 ? model::Phase::settle : model::Phase::heating);
    run.step.push_back(static_cast<int>(i / 3600));
    run.flags.push_back(0);
  }
  return run;
}

std::filesystem::path fresh(const std::filesystem::path& dir, const std::string& name) {
  const auto path = dir / name;
  for (const char* suffix : {"", "-wal", "-shm"})
    std::filesystem::remove(path.string() + suffix);
  return path;
}

bool bench_import(const std::filesystem::path& dir, std::size_t rows) {
  const model::RunData run = make_run(rows);
  const auto path = fresh(dir, "import_" + std::to_string(rows) + ".db");
  auto store = Store::open(path);
  if (!store) {
    std::fprintf(stderr, "%s\n", store.error().message.c_str());
    return false;
  }
  ImportOptions options;
  options.serial = "FOG-BENCH";
  const auto t0 = Clock::now();
  auto id = store->import_run(run, options);
  const double import_s = seconds_since(t0);
  if (!id) {
    std::fprintf(stderr, "%s\n", id.error().message.c_str());
    return false;
  }
  const auto t1 = Clock::now();
  ExportOptions all;
  all.include_settle = true;
  auto back = store->export_run(*id, 0, all);
  const double export_s = seconds_since(t1);
  if (!back || back->size() != rows) {
    std::fprintf(stderr, "export failed\n");
    return false;
  }
  const auto bytes = std::filesystem::file_size(path) +
                     (std::filesystem::exists(path.string() + "-wal")
                          ? std::filesystem::file_size(path.string() + "-wal")
                          : 0);
  std::printf(
      "import_run rows=%zu import_s=%.3f rows_per_s=%.0f export_s=%.3f export_rows_per_s=%.0f "
      "bytes_per_row=%.0f\n",
      rows, import_s, static_cast<double>(rows) / import_s, export_s,
      static_cast<double>(rows) / export_s, static_cast<double>(bytes) / static_cast<double>(rows));
  return true;
}

bool bench_append(const std::filesystem::path& dir, bool synchronous_full, int calls) {
  const auto path = fresh(dir, std::string("append_") + (synchronous_full ? "full" : "normal") + ".db");
  OpenOptions o;
  o.synchronous_full = synchronous_full;
  auto store = Store::open(path, o);
  if (!store) {
    std::fprintf(stderr, "%s\n", store.error().message.c_str());
    return false;
  }
  NewRun r;
  r.profile_name = "bench";
  for (int u = 0; u < 8; ++u) r.unit_serials.push_back("FOG-" + std::to_string(u));
  auto run = store->create_run(r);
  if (!run) return false;

  std::vector<double> ms;
  ms.reserve(static_cast<std::size_t>(calls));
  std::vector<SampleRow> rows(8);
  const auto start = Clock::now();
  for (int second = 0; second < calls; ++second) {
    for (int u = 0; u < 8; ++u) {
      SampleRow& s = rows[static_cast<std::size_t>(u)];
      s.unit_index = u;
      s.t_s = second;
      s.wall_time = 1.7e9 + second;
      s.setpoint_c = 23;
      s.chamber_c = 23.4;
      s.gyro_dph = 0.01 * u;
      s.frames = 2000;
      s.t1_c = 23.1;
      s.t2_c = 23.2;
      s.phase = model::Phase::hold;
      s.step = 1;
    }
    const auto t0 = Clock::now();
    if (auto ok = store->append_samples(*run, rows); !ok) {
      std::fprintf(stderr, "%s\n", ok.error().message.c_str());
      return false;
    }
    ms.push_back(seconds_since(t0) * 1e3);
  }
  const double total_s = seconds_since(start);
  std::sort(ms.begin(), ms.end());
  double mean = 0;
  for (double v : ms) mean += v;
  mean /= static_cast<double>(ms.size());
  std::printf(
      "append_samples synchronous=%s calls=%d rows_per_call=8 rows_per_s=%.0f ms_per_call_mean=%.3f "
      "p50=%.3f p99=%.3f max=%.3f\n",
      synchronous_full ? "FULL" : "NORMAL", calls, 8.0 * calls / total_s, mean,
      ms[ms.size() / 2], ms[ms.size() * 99 / 100], ms.back());
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  // A directory on the disk under test; /tmp by default (may be tmpfs: pass a real disk).
  const std::filesystem::path base =
      argc > 1 ? std::filesystem::path(argv[1]) : std::filesystem::temp_directory_path();
  const auto dir = base / ("fogbench_bench_store_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  bool ok = bench_import(dir, 86'400) && bench_import(dir, 1'000'000) &&
            bench_append(dir, true, 3000) && bench_append(dir, false, 3000);
  std::filesystem::remove_all(dir);
  return ok ? 0 : 1;
}
