// Benchmark of workbench::diagnose on an exp1-length fit run (5400 s, a hidden 0.05 deg/h per
// degC of T1) with two held-out runs (exp2, exp3; 18,900 samples in all): the full search over
// the term language (the default; target under 1 s on one core, issue 10), the library alone
// (target under 100 ms, issue 5), and its parts (one fit, compare).
#include <algorithm>
#include <chrono>
#include <ctime>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <vector>

#include "fogbench/model/model.hpp"
#include "fogbench/model/workbench.hpp"
#include "fogbench/profiles/profile.hpp"
#include "fogbench/sim/sim.hpp"

using namespace fogbench;
using Clock = std::chrono::steady_clock;

namespace {

model::RunData simulate(const std::string& name, std::uint64_t seed, const std::string& effect) {
  std::ifstream f(std::string(FOGBENCH_SOURCE_DIR) + "/profiles/" + name + ".profile");
  std::stringstream ss;
  ss << f.rdbuf();
  auto p = profiles::parse_profile(ss.str(), name);
  if (!p) {
    std::fprintf(stderr, "profile %s: cannot parse\n", name.c_str());
    std::exit(2);
  }
  std::vector<sim::SetpointSample> prog;
  for (const auto& pt : profiles::nominal_setpoints(*p, 1.0)) {
    if (pt.phase == profiles::Phase::settle) continue;
    const model::Phase ph = pt.phase == profiles::Phase::heating   ? model::Phase::heating
                            : pt.phase == profiles::Phase::cooling ? model::Phase::cooling
                                                                   : model::Phase::hold;
    prog.push_back({pt.setpoint_c, ph, static_cast<int>(pt.step_index)});
  }
  sim::SimConfig cfg;
  cfg.seed = seed;
  cfg.units[0].effects = effect;
  auto r = sim::simulate(cfg, prog);
  if (!r) {
    std::fprintf(stderr, "simulate %s: %s\n", name.c_str(), r.error().c_str());
    std::exit(2);
  }
  auto run = r->front();
  run.name = name;
  return run;
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

int main() {
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
  std::printf("  fit paper (2 terms)  median %7.2f ms  min %7.2f ms\n", fit_med, fit_min);
  std::printf("  fit paper + T1       median %7.2f ms  min %7.2f ms\n", fit3_med, fit3_min);
  std::printf("  compare (exp1)       median %7.2f ms  min %7.2f ms\n", cmp_med, cmp_min);
  return lang_cpu < 1000.0 ? 0 : 1;
}
