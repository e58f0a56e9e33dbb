// diagnose's peak heap (issue 30, point 1: under 3 x the input's size). The malloc family is
// interposed (as bench_fit_alloc does) and the bytes live at once are followed
// (malloc_usable_size of each block), so the figure is the heap's high-water mark during one
// diagnose call above what was live before it, not the process's RSS; on one thread
// (DiagnoseOptions::threads 1) it is the same on every run and machine, on two it depends on
// how the threads meet. The input's size is the run as the CSV reader holds it in memory (its
// columns' bytes: time, gyro, T1, T2, setpoint, chamber as doubles, phase, step and flags).
// Usage:
//   bench_diagnose_peak [--cycles 48] [--threads 1] [--search language|library] [--max-ratio R] [--stages 1]
// --cycles: the 3-day profile's 1 h 30 min cycles (48: 262,200 samples; 159: about 10 days);
// --max-ratio: exit 1 when the peak is above R x the input (a watch, not a target).
// --stages 1: also the peak within each of diagnose's stages as its progress reports them (the
// stage the calling thread last reported, with the search's step: on one thread each figure is
// that stage's own; on two, a stage run beside the calling thread counts in the caller's).
#include <malloc.h>

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <expected>
#include <string>
#include <vector>

#include "fogbench/model/model.hpp"
#include "fogbench/model/workbench.hpp"
#include "fogbench/profiles/profile.hpp"
#include "fogbench/sim/sim.hpp"
#include "profile_run.hpp"

extern "C" {
void* __libc_malloc(std::size_t);
void* __libc_calloc(std::size_t, std::size_t);
void* __libc_realloc(void*, std::size_t);
void* __libc_memalign(std::size_t, std::size_t);
void __libc_free(void*);
}

namespace {

std::atomic<long> live_bytes{0};
std::atomic<long> peak_bytes{0};
std::atomic<long> stage_peak_bytes{0};  // since the last stage reported (--stages)

void raise(std::atomic<long>& peak, long now) {
  long seen = peak.load(std::memory_order_relaxed);
  while (now > seen && !peak.compare_exchange_weak(seen, now, std::memory_order_relaxed)) {
  }
}
void grew(void* p) {
  if (!p) return;
  const long now = live_bytes.fetch_add(static_cast<long>(malloc_usable_size(p)), std::memory_order_relaxed) +
                   static_cast<long>(malloc_usable_size(p));
  raise(peak_bytes, now);
  raise(stage_peak_bytes, now);
}
void shrank(void* p) {
  if (p) live_bytes.fetch_sub(static_cast<long>(malloc_usable_size(p)), std::memory_order_relaxed);
}

}  // namespace

// The executable's symbols come first: every allocation of the process (operator new, Eigen's
// and FFTW's aligned ones) goes through these, then to glibc's own.
extern "C" {
void* malloc(std::size_t n) {
  void* p = __libc_malloc(n);
  grew(p);
  return p;
}
void* calloc(std::size_t k, std::size_t n) {
  void* p = __libc_calloc(k, n);
  grew(p);
  return p;
}
void* realloc(void* p, std::size_t n) {
  shrank(p);
  void* q = __libc_realloc(p, n);
  grew(q ? q : (n ? p : nullptr));  // a failed realloc leaves p as it was
  return q;
}
void free(void* p) {
  shrank(p);
  __libc_free(p);
}
void* memalign(std::size_t a, std::size_t n) {
  void* p = __libc_memalign(a, n);
  grew(p);
  return p;
}
void* aligned_alloc(std::size_t a, std::size_t n) {
  void* p = __libc_memalign(a, n);
  grew(p);
  return p;
}
int posix_memalign(void** out, std::size_t a, std::size_t n) {
  void* p = __libc_memalign(a, n);
  if (!p) return 12;  // ENOMEM
  grew(p);
  *out = p;
  return 0;
}
}

using namespace fogbench;

namespace {

// bench_diagnose's 3-day profile with `cycles` cycles of exp1's steps (48: 262,200 s at 1 Hz).
std::expected<model::RunData, std::string> simulate(int cycles, std::uint64_t seed, const std::string& effect) {
  return bench::simulate_profile_text(bench::long_profile(cycles), "long" + std::to_string(cycles), seed, effect);
}

// The run's columns as held in memory (sizes, not capacities: what a reader of the CSV must hold).
std::size_t input_bytes(const model::RunData& r) {
  auto b = [](const auto& v) { return v.size() * sizeof(v[0]); };
  return b(r.time_s) + b(r.gyro_dph) + b(r.t1_c) + b(r.t2_c) + b(r.setpoint_c) + b(r.chamber_c) + b(r.phase) + b(r.step) +
         b(r.flags) + b(r.since_power_on_s) + b(r.compensated_dph) + b(r.rate_in_dps) + b(r.gyro_y_dph) + b(r.gyro_z_dph);
}

}  // namespace

int main(int argc, char** argv) {
  int cycles = 48, threads = 1, stages = 0;
  double max_ratio = 0.0;
  std::string search = "language";
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string a = argv[i], v = argv[i + 1];
    if (a == "--cycles") cycles = std::atoi(v.c_str());
    else if (a == "--threads") threads = std::atoi(v.c_str());
    else if (a == "--max-ratio") max_ratio = std::atof(v.c_str());
    else if (a == "--search") search = v;
    else if (a == "--stages") stages = std::atoi(v.c_str());
    else {
      std::fprintf(stderr,
                   "bench_diagnose_peak: unknown option %s (--cycles N, --threads N, --search language|library, --max-ratio R, --stages 1)\n",
                   a.c_str());
      return 2;
    }
  }
  if (cycles < 1 || cycles > 400 || threads < 0 || (search != "language" && search != "library")) {
    std::fprintf(stderr, "bench_diagnose_peak: --cycles must be 1 to 400, --threads 0 or more, --search language or library\n");
    return 2;
  }
  auto run = simulate(cycles, 11, "0.05*T1");
  if (!run) {
    std::fprintf(stderr, "bench_diagnose_peak: simulate: %s\n", run.error().c_str());
    return 2;
  }
  auto m = model::fit(*run, *model::parse_terms("paper"));
  if (!m) {
    std::fprintf(stderr, "bench_diagnose_peak: fit: %s\n", m.error().message.c_str());
    return 2;
  }
  model::workbench::DiagnoseOptions o;
  o.threads = threads;
  o.search = search == "library" ? model::workbench::DiagnoseOptions::Search::library : model::workbench::DiagnoseOptions::Search::language;
  // The stages in the order first reported, each with its peak (bytes above `before`).
  std::vector<std::pair<std::string, long>> by_stage{{"(before the first report)", 0}};
  std::size_t at = 0;
  const long before = live_bytes.load();
  auto close_stage = [&] { by_stage[at].second = std::max(by_stage[at].second, stage_peak_bytes.load() - before); };
  if (stages)
    o.progress = [&](const model::workbench::DiagnoseProgress& p) {
      const std::string key = p.stage + ", step " + std::to_string(p.step);
      if (key == by_stage[at].first) return;
      close_stage();
      stage_peak_bytes = live_bytes.load();
      auto it = std::find_if(by_stage.begin(), by_stage.end(), [&](const auto& e) { return e.first == key; });
      if (it == by_stage.end()) it = by_stage.insert(by_stage.end(), {key, 0});
      at = static_cast<std::size_t>(it - by_stage.begin());
    };
  peak_bytes = before;
  stage_peak_bytes = before;
  auto d = model::workbench::diagnose(*m, *run, {}, o);
  const long peak = peak_bytes.load() - before;
  close_stage();
  if (!d) {
    std::fprintf(stderr, "bench_diagnose_peak: diagnose: %s\n", d.error().message.c_str());
    return 2;
  }
  const double in = static_cast<double>(input_bytes(*run));
  const double ratio = static_cast<double>(peak) / in;
  std::printf("diagnose (%s search, threads %d) on %zu samples: input %.1f MB in memory, peak heap above it %.1f MB = %.2f x the input\n",
              search.c_str(), threads, run->size(), in / 1e6, static_cast<double>(peak) / 1e6, ratio);
  if (stages)
    for (const auto& [stage, bytes] : by_stage)
      std::printf("  %-32s peak %7.1f MB = %.2f x the input\n", stage.c_str(), static_cast<double>(bytes) / 1e6,
                  static_cast<double>(bytes) / in);
  if (max_ratio > 0.0 && ratio > max_ratio) {
    std::printf("above --max-ratio %.2f\n", max_ratio);
    return 1;
  }
  return 0;
}
