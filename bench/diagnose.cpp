// Benchmark of workbench::diagnose on an exp1-length fit run (5400 s, a hidden 0.05 deg/h per
// degC of T1) with two held-out runs (exp2, exp3; 18,900 samples in all): the full search over
// the term language (the default; target under 1 s on one core, issue 10), the library alone
// (target under 100 ms, issue 5), and its parts (one fit, compare); then a 3-day run alone
// (262,200 samples; target under 5 s on both cores, issue 25 point 6) and its ratio to the 3-run case.
// `bench_diagnose --long REPS [THREADS]`: the 3-day case alone (see long_only).
#include <algorithm>
#include <chrono>
#include <ctime>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <fstream>
#include <sstream>
#include <vector>

#include "fogbench/model/model.hpp"
#include "fogbench/model/workbench.hpp"
#include "fogbench/profiles/profile.hpp"
#include "fogbench/sim/sim.hpp"
#include "profile_run.hpp"

using namespace fogbench;
using Clock = std::chrono::steady_clock;

namespace {

// A shipped profile (profiles/NAME.profile) or "long3d" (three days, bench::long_profile),
// simulated; exits 2 naming what failed.
model::RunData simulate(const std::string& name, std::uint64_t seed, const std::string& effect) {
  std::string text;
  if (name == "long3d") {
    text = bench::long_profile();
  } else {
    std::ifstream f(std::string(FOGBENCH_SOURCE_DIR) + "/profiles/" + name + ".profile");
    std::stringstream ss;
    ss << f.rdbuf();
    text = ss.str();
  }
  auto run = bench::simulate_profile_text(text, name, seed, effect);
  if (!run) {
    std::fprintf(stderr, "%s\n", run.error().c_str());
    std::exit(2);
  }
  return std::move(*run);
}

// Median and minimum over `reps` calls of fn, in ms of wall time; the machine is shared, so
// the process's CPU time per call (std::clock) is printed beside it.
double g_cpu_ms = 0.0;
template <class Fn>
std::pair<double, double> time_ms(int reps, Fn fn) {
  std::vector<double> t;
  const std::clock_t c0 = std::clock();
  for (int i = 0; i < reps; ++i) {
    const auto a = Clock::now();
    fn();
    t.push_back(std::chrono::duration<double, std::milli>(Clock::now() - a).count());
  }
  g_cpu_ms = 1000.0 * static_cast<double>(std::clock() - c0) / CLOCKS_PER_SEC / reps;
  std::sort(t.begin(), t.end());
  return {t[t.size() / 2], t.front()};
}

}  // namespace

// --long REPS [THREADS]: the 3-day case only, REPS calls on THREADS threads (default 1; 0: as
// fogctl, the machine's cores), each call's CPU time (the process's, std::clock) and wall time,
// then min and median of each: the figures docs/performance.md compares before and after.
int long_only(int reps, int threads) {
  const model::RunData long_run = simulate("long3d", 11, "0.05*T1");
  auto ml = model::fit(long_run, *model::parse_terms("paper"));
  if (!ml) {
    std::fprintf(stderr, "fit long3d: %s\n", ml.error().message.c_str());
    return 2;
  }
  model::workbench::DiagnoseOptions o;
  o.threads = threads;
  std::vector<double> cpu, wall;
  std::size_t refitted = 0;
  for (int i = 0; i < reps; ++i) {
    const std::clock_t c0 = std::clock();
    const auto a = Clock::now();
    auto d = model::workbench::diagnose(*ml, long_run, {}, o);
    if (!d) return 2;
    refitted = d->search_space.value("refitted", 0u);
    wall.push_back(std::chrono::duration<double>(Clock::now() - a).count());
    cpu.push_back(static_cast<double>(std::clock() - c0) / CLOCKS_PER_SEC);
    std::printf("  call %d: cpu %.2f s, wall %.2f s\n", i + 1, cpu.back(), wall.back());
    std::fflush(stdout);
  }
  std::sort(cpu.begin(), cpu.end());
  std::sort(wall.begin(), wall.end());
  std::printf("3-day run (%zu samples), language search, threads %d, %zu refitted, %d calls: cpu min %.2f s median %.2f s; wall min %.2f s median %.2f s\n",
              long_run.size(), threads, refitted, reps, cpu.front(), cpu[cpu.size() / 2], wall.front(), wall[wall.size() / 2]);
  return 0;
}

int main(int argc, char** argv) {
  if (argc >= 2 && (std::string(argv[1]) == "--help" || std::string(argv[1]) == "-h")) {
    std::printf(
        "bench_diagnose: workbench::diagnose on exp1 (fit) with exp2, exp3 held out (library and language search, "
        "wall and CPU per call), then the 3-day run (262,200 samples)\n"
        "  bench_diagnose                     the whole benchmark\n"
        "  bench_diagnose --long REPS [THREADS]  the 3-day run alone, REPS calls on THREADS threads (0: all cores)\n");
    return 0;
  }
  if (argc == 2 && std::string(argv[1]) == "--long") {
    std::fprintf(stderr, "bench_diagnose: --long needs REPS (see --help)\n");
    return 2;
  }
  if (argc >= 2 && std::string(argv[1]) != "--long") {
    std::fprintf(stderr, "bench_diagnose: unknown argument '%s' (see --help)\n", argv[1]);
    return 2;
  }
  if (argc >= 3 && std::string(argv[1]) == "--long") return long_only(std::max(1, std::atoi(argv[2])), argc >= 4 ? std::atoi(argv[3]) : 1);
  const std::string effect = "0.05*T1";
  std::vector<model::RunData> runs{simulate("exp1", 7, effect), simulate("exp2", 8, effect), simulate("exp3", 9, effect)};
  const std::span<const model::RunData> held = std::span<const model::RunData>(runs).subspan(1);
  auto m = model::fit(runs[0], *model::parse_terms("paper"));
  if (!m) {
    std::fprintf(stderr, "fit: %s\n", m.error().message.c_str());
    return 2;
  }
  std::size_t evaluated = 0;
  std::string top;
  model::workbench::DiagnoseOptions lib;
  lib.search = model::workbench::DiagnoseOptions::Search::library;
  const auto [diag_med, diag_min] = time_ms(20, [&] {
    auto d = model::workbench::diagnose(*m, runs[0], held, lib);
    if (!d) std::exit(2);
    evaluated = 0;
    for (const auto& c : d->candidates) evaluated += c.evaluated;
    top = d->candidates.front().term;
  });
  const double diag_cpu = g_cpu_ms;
  // The full search over the term language (the default options).
  std::size_t total = 0, scanned = 0, refitted = 0, steps = 0;
  const auto [lang_med, lang_min] = time_ms(5, [&] {
    auto d = model::workbench::diagnose(*m, runs[0], held);
    if (!d) std::exit(2);
    total = d->search_space.value("total", 0u);
    scanned = d->search_space.value("scanned", 0u);
    refitted = d->search_space.value("refitted", 0u);
    steps = d->steps.size();
  });
  const double lang_cpu = g_cpu_ms;
  model::workbench::DiagnoseOptions two = lib;
  two.threads = 2;
  const auto [d2_med, d2_min] = time_ms(20, [&] { (void)model::workbench::diagnose(*m, runs[0], held, two); });
  const double d2_cpu = g_cpu_ms;
  const auto [fit_med, fit_min] = time_ms(20, [&] { (void)model::fit(runs[0], *model::parse_terms("paper")); });
  auto t3 = model::parse_terms("d(T1)@auto + grad@auto + T1");
  const auto [fit3_med, fit3_min] = time_ms(20, [&] { (void)model::fit(runs[0], *t3); });
  const auto [cmp_med, cmp_min] = time_ms(20, [&] { (void)model::workbench::compare(*m, runs[0]); });
  std::printf("diagnose: fit run exp1 (%zu s), held out exp2 (%zu s) and exp3 (%zu s), hidden effect %s\n", runs[0].size(),
              runs[1].size(), runs[2].size(), effect.c_str());
  std::printf("  language search: %zu candidates in the space, %zu lag-scanned, %zu refitted over %zu greedy step(s) and the final search\n",
              total, scanned, refitted, steps);
  std::printf("  diagnose, language   median %7.1f ms  min %7.1f ms  cpu %7.1f ms per call (target < 1000 ms); cpu %.2f ms per candidate of the space\n",
              lang_med, lang_min, lang_cpu, total ? lang_cpu / static_cast<double>(total) : 0.0);
  std::printf("  library: %zu candidates refitted, top: %s\n", evaluated, top.c_str());
  std::printf("  diagnose, library    median %7.1f ms  min %7.1f ms  cpu %7.1f ms per call (target < 100 ms)\n", diag_med, diag_min, diag_cpu);
  std::printf("  diagnose, 2 threads  median %7.1f ms  min %7.1f ms  cpu %7.1f ms per call (not the default: see DiagnoseOptions::threads)\n", d2_med, d2_min, d2_cpu);
  // Issue 25/30: a 3-day run (262,200 samples) alone, the language search, as fogctl runs it
  // (threads 0: both cores) and on one thread; CPU per call and the ratio to the 3-run case.
  const model::RunData long_run = simulate("long3d", 11, effect);
  auto ml = model::fit(long_run, *model::parse_terms("paper"));
  if (!ml) {
    std::fprintf(stderr, "fit long3d: %s\n", ml.error().message.c_str());
    return 2;
  }
  model::workbench::DiagnoseOptions both;
  both.threads = 0;
  std::size_t long_refitted = 0;
  const auto [long_med, long_min] = time_ms(3, [&] {
    auto d = model::workbench::diagnose(*ml, long_run, {}, both);
    if (!d) std::exit(2);
    long_refitted = d->search_space.value("refitted", 0u);
  });
  const double long_cpu = g_cpu_ms;
  model::workbench::DiagnoseOptions one;
  const auto [long1_med, long1_min] = time_ms(1, [&] { (void)model::workbench::diagnose(*ml, long_run, {}, one); });
  const double long1_cpu = g_cpu_ms;
  const auto [lang2_med, lang2_min] = time_ms(5, [&] { (void)model::workbench::diagnose(*m, runs[0], held, both); });
  std::printf("  3-day run (%zu samples), language search, %zu refitted:\n", long_run.size(), long_refitted);
  std::printf("    both cores (as fogctl) median %8.1f ms  min %8.1f ms  cpu %8.1f ms per call (target < 5000 ms wall)\n", long_med, long_min, long_cpu);
  std::printf("    one thread             median %8.1f ms  min %8.1f ms  cpu %8.1f ms per call\n", long1_med, long1_min, long1_cpu);
  std::printf("    ratio to the 3-run case (both cores, wall median %.1f ms): %.1f; samples ratio %.1f\n", lang2_med,
              lang2_med > 0 ? long_med / lang2_med : 0.0,
              static_cast<double>(long_run.size()) / static_cast<double>(runs[0].size() + runs[1].size() + runs[2].size()));
  std::printf("  fit paper (2 terms)  median %7.2f ms  min %7.2f ms\n", fit_med, fit_min);
  std::printf("  fit paper + T1       median %7.2f ms  min %7.2f ms\n", fit3_med, fit3_min);
  std::printf("  compare (exp1)       median %7.2f ms  min %7.2f ms\n", cmp_med, cmp_min);
  return lang_cpu < 1000.0 ? 0 : 1;
}
