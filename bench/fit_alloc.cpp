// The fits' heap allocations (issue 30, point 3): a counting allocator around glibc's malloc
// family (operator new, Eigen's and FFTW's aligned allocations all end there) counts the calls
// and bytes of
//   - a paper fit and a joint fit of the same run (after one warm-up fit: FFTW's plans and the
//     per-thread transform buffers exist),
//   - each Cochrane-Orcutt iteration of the joint fit: the fit run with max_iterations = k for
//     k = 1, 2, ..., and the difference between consecutive counts (an iteration's own
//     allocations; the fit's set-up and finish are the same in both),
//   - the lag scan alone: LagScanner::corr and scan() called again on columns they have seen.
// Counts, not times: the figure is the same on any machine. Usage:
//   bench_fit_alloc [--sizes 86400,864000] [--iterations K]
#include <execinfo.h>
#include <malloc.h>

#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "fit_internal.hpp"
#include "fogbench/model/model.hpp"
#include "cycling.hpp"
#include "fogbench/sim/sim.hpp"

extern "C" {
void* __libc_malloc(std::size_t);
void* __libc_calloc(std::size_t, std::size_t);
void* __libc_realloc(void*, std::size_t);
void* __libc_memalign(std::size_t, std::size_t);
void __libc_free(void*);
}

namespace {

std::atomic<bool> counting{false};
bool trace = false;  // FOGBENCH_ALLOC_TRACE=1: a backtrace of each counted allocation on stderr
std::atomic<long> calls{0};
std::atomic<long> bytes{0};

void count(std::size_t n) {
  if (counting.load(std::memory_order_relaxed)) {
    calls.fetch_add(1, std::memory_order_relaxed);
    bytes.fetch_add(static_cast<long>(n), std::memory_order_relaxed);
    if (trace) {
      counting = false;  // backtrace() allocates on its first call
      void* frames[12];
      const int k = backtrace(frames, 12);
      std::fprintf(stderr, "-- allocation of %zu B\n", n);
      backtrace_symbols_fd(frames, k, 2);
      counting = true;
    }
  }
}

}  // namespace

// The malloc family interposed (the executable's symbols come first): each call counted when
// counting is on, then handed to glibc's own.
extern "C" {
void* malloc(std::size_t n) {
  count(n);
  return __libc_malloc(n);
}
void* calloc(std::size_t k, std::size_t n) {
  count(k * n);
  return __libc_calloc(k, n);
}
void* realloc(void* p, std::size_t n) {
  count(n);
  return __libc_realloc(p, n);
}
void free(void* p) { __libc_free(p); }
void* memalign(std::size_t a, std::size_t n) {
  count(n);
  return __libc_memalign(a, n);
}
void* aligned_alloc(std::size_t a, std::size_t n) {
  count(n);
  return __libc_memalign(a, n);
}
int posix_memalign(void** out, std::size_t a, std::size_t n) {
  count(n);
  void* p = __libc_memalign(a, n);
  if (!p) return 12;  // ENOMEM
  *out = p;
  return 0;
}
}

using namespace fogbench;

namespace {

struct Count {
  long calls = 0, bytes = 0;
};

template <class F>
Count counted(F&& f) {
  calls = 0;
  bytes = 0;
  counting = true;
  f();
  counting = false;
  return {calls.load(), bytes.load()};
}

std::string human(long b) {
  char s[32];
  if (b >= 10L << 20) std::snprintf(s, sizeof s, "%.1f MB", static_cast<double>(b) / (1 << 20));
  else if (b >= 10L << 10) std::snprintf(s, sizeof s, "%.1f kB", static_cast<double>(b) / (1 << 10));
  else std::snprintf(s, sizeof s, "%ld B", b);
  return s;
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<std::size_t> sizes = {86400, 864000};
  int max_k = 6;
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--iterations") && i + 1 < argc) max_k = std::atoi(argv[++i]);
    else if (!std::strcmp(argv[i], "--sizes") && i + 1 < argc) {
      sizes.clear();
      for (char* s = std::strtok(argv[++i], ","); s; s = std::strtok(nullptr, ",")) sizes.push_back(std::strtoul(s, nullptr, 10));
    } else {
      std::fprintf(stderr, "usage: bench_fit_alloc [--sizes N,N,...] [--iterations K]\n");
      return 2;
    }
  }
  const bool want_trace = std::getenv("FOGBENCH_ALLOC_TRACE") != nullptr;
  const auto paper = *model::parse_terms("paper");
  const auto joint_terms = *model::parse_terms("d(T1)@auto + grad@auto");
  for (std::size_t n : sizes) {
    sim::SimConfig cfg;
    cfg.seed = 5;
    auto runs = sim::simulate(cfg, bench::cycling_program(n));
    if (!runs) {
      std::fprintf(stderr, "simulation failed: %s\n", runs.error().c_str());
      return 1;
    }
    const model::RunData& run = runs->front();
    std::printf("N = %zu samples (the run in memory: %s)\n", n,
                human(static_cast<long>(n * sizeof(double) * 6)).c_str());
    model::FitOptions po, jo;
    jo.method = model::Method::joint;
    bool ok = true;
    for (const auto& [name, terms, o] : {std::tuple{"paper", paper, po}, std::tuple{"joint", joint_terms, jo}}) {
      (void)model::fit(run, terms, o);  // warm-up: FFTW's plans, the per-thread buffers
      model::FitSummary s;
      const Count c = counted([&] {
        auto m = model::fit(run, terms, o);
        ok = ok && m.has_value();
        if (m) s = m->fit.summary;
      });
      std::printf("  %s fit: %ld allocations, %s (%d iterations)\n", name, c.calls, human(c.bytes).c_str(),
                  s.iterations);
    }
    // Each Cochrane-Orcutt iteration's own allocations: fits of k and k - 1 iterations differ by
    // the k-th iteration.
    std::printf("  joint fit, the k-th Cochrane-Orcutt iteration's own allocations:\n");
    Count before{};
    int done_before = 0;
    for (int k = 1; k <= max_k; ++k) {
      model::FitOptions o = jo;
      o.max_iterations = k;
      int done = 0;
      trace = want_trace;  // the iterations' fits only
      if (trace) std::fprintf(stderr, "== fit of at most %d iterations\n", k);
      const Count c = counted([&] {
        auto m = model::fit(run, joint_terms, o);
        if (m) done = m->fit.iterations;
      });
      trace = false;
      if (k > 1 && done > done_before)
        std::printf("    iteration %d: %ld allocations, %s\n", done, c.calls - before.calls,
                    human(c.bytes - before.bytes).c_str());
      if (done <= done_before) break;  // converged: no more iterations to count
      before = c;
      done_before = done;
    }
    // The lag scan alone, on columns it has seen (their spectra made).
    {
      const int L = 600;
      std::vector<double> w(n, 1.0), y(run.gyro_dph.begin(), run.gyro_dph.end());
      model::detail::LagScanner sc(n, L, w);
      const model::detail::Lagged x = model::detail::make_lagged(run.t1_c, L);
      const model::detail::Lagged g = model::detail::make_lagged(run.t2_c, L);
      const model::detail::Spectrum ys = sc.spectrum_of_target(y);
      sc.ready(x);
      sc.ready(g);
      std::vector<double> c0;
      sc.corr(x, ys, c0);
      const Count corr = counted([&] { sc.corr(x, ys, c0); });
      std::printf("  lag scan: LagScanner::corr (one regressor's %d lags): %ld allocations, %s\n", L + 1, corr.calls,
                  human(corr.bytes).c_str());
      const std::vector<model::detail::Column> fixed{{nullptr, 1.0}};
      const std::vector<const model::detail::Lagged*> var{&x, &g};
      (void)model::detail::scan(sc, y, &ys, fixed, var, 0, L);
      const Count sc2 = counted([&] { (void)model::detail::scan(sc, y, &ys, fixed, var, 0, L); });
      std::printf("  lag scan: scan() (intercept + 2 regressors, %d lags): %ld allocations, %s\n", L + 1, sc2.calls,
                  human(sc2.bytes).c_str());
    }
    if (!ok) {
      std::fprintf(stderr, "a fit failed\n");
      return 1;
    }
    std::fflush(stdout);
  }
  return 0;
}
