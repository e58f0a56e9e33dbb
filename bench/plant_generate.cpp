// bench_plant_generate: fills a plant store with a generated fleet (plant/generate.hpp) and
// times `fleet spc` over it (every figure: query, chart, rules), the issue 14 figure (< 1 s).
//   bench_plant_generate --db "host=/tmp/pg port=5433 user=postgres dbname=postgres" [--runs 10000]
//                        [--sample-runs N] [--no-generate]
// Every run gets its samples (10,000 runs x 2 units x 10,000 s: 200 million rows) unless
// --sample-runs limits them to the first N runs. Progress on stderr: a line rewritten in place on
// a terminal, a line every 5% otherwise.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <string>

#include <unistd.h>

#include "fogbench/plant/fleet_spc.hpp"
#include "fogbench/plant/generate.hpp"
#include "fogbench/plant/verdicts.hpp"

using namespace fogbench;
using Clock = std::chrono::steady_clock;

int main(int argc, char** argv) {
  std::string db;
  plant::GenerateOptions o;
  // Bench 3 gives marginal verdicts at 20% (5% elsewhere) from the middle of the plant on: the
  // p-charts have a bench to flag.
  o.marginal_bench = 3;
  o.marginal_from_run = o.runs / 2;
  bool generate = true;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--help" || a == "-h") {
      std::printf("bench_plant_generate --db CONNSTR [--runs N] [--sample-runs N] [--marginal-bench K] [--no-generate]\n"
                  "  fills the plant store with a generated fleet (default 10,000 runs of 2 units, every run's\n"
                  "  samples: 200 million rows; --sample-runs N: samples for the first N runs only) and times\n"
                  "  fleet spc over it. --marginal-bench K: the bench given extra marginal verdicts from the middle\n"
                  "  of the plant on (default 3; 0: none). --no-generate: time fleet spc over what the plant holds.\n");
      return 0;
    }
    if (a == "--db" && i + 1 < argc) db = argv[++i];
    else if (a == "--runs" && i + 1 < argc) o.runs = std::stoi(argv[++i]), o.marginal_from_run = o.runs / 2;
    else if (a == "--marginal-bench" && i + 1 < argc) o.marginal_bench = std::stoi(argv[++i]);
    else if (a == "--sample-runs" && i + 1 < argc) o.sample_runs = std::stoi(argv[++i]);
    else if (a == "--no-generate") generate = false;
    else {
      std::fprintf(stderr, "usage: bench_plant_generate --db CONNSTR [--runs N] [--sample-runs N] [--marginal-bench K] [--no-generate]\n");
      return 2;
    }
  }
  if (db.empty()) return std::fprintf(stderr, "bench_plant_generate: --db is required\n"), 2;
  auto c = plant::Connection::open(db, true);
  if (!c) return std::fprintf(stderr, "%s\n", c.error().message.c_str()), 1;
  if (generate) {
    const auto t0 = Clock::now();
    const bool tty = ::isatty(2) != 0;
    int last_pct = -1;
    o.progress = [&](std::int64_t done, std::int64_t total, std::int64_t rows) {
      const double s = std::chrono::duration<double>(Clock::now() - t0).count();
      const int pct = static_cast<int>(100 * done / total);
      if (!tty && pct / 5 == last_pct / 5 && done != total) return;
      if (tty && pct == last_pct && done != total && done % 20 != 0) return;
      last_pct = pct;
      const double rate = s > 0 ? static_cast<double>(rows) / s : 0;
      const double eta = done > 0 ? s * static_cast<double>(total - done) / static_cast<double>(done) : 0;
      std::fprintf(stderr, "%ssamples: run %lld of %lld (%d%%), %lld rows, %.0f rows/s, %.0f s elapsed, ~%.0f s to go%s",
                   tty ? "\r" : "", static_cast<long long>(done), static_cast<long long>(total), pct,
                   static_cast<long long>(rows), rate, s, eta, tty ? "   " : "\n");
      if (tty && done == total) std::fprintf(stderr, "\n");
    };
    auto g = plant::generate_fleet(*c, o);
    if (!g) return std::fprintf(stderr, "%s\n", g.error().message.c_str()), 1;
    const double s = std::chrono::duration<double>(Clock::now() - t0).count();
    std::printf("generated %lld runs, %lld units, %lld figures, %lld samples in %.1f s; shifted lot %s; outliers:",
                static_cast<long long>(g->runs), static_cast<long long>(g->units), static_cast<long long>(g->figures),
                static_cast<long long>(g->samples), s, g->shifted_lot.c_str());
    for (const auto& x : g->outlier_serials) std::printf(" %s", x.c_str());
    std::printf("\n");
    (void)c->exec("ANALYZE", "analyze");
  }
  // fleet spc over every figure, as `fogctl fleet spc` does it (query, chart, rules); best of 5.
  double best = 1e9, best_one = 1e9;
  std::size_t flagged = 0, values = 0;
  std::string flagged_benches;
  for (int rep = 0; rep < 5; ++rep) {
    const auto t0 = Clock::now();
    auto names = plant::figure_names(*c, {});
    if (!names) return std::fprintf(stderr, "%s\n", names.error().message.c_str()), 1;
    flagged = values = 0;
    double one = 0;
    for (const auto& n : *names) {
      const auto t1 = Clock::now();
      auto v = plant::figure_values(*c, n.name, {});
      if (!v) return std::fprintf(stderr, "%s\n", v.error().message.c_str()), 1;
      plant::Baseline b;
      b.first_n = 2000;
      auto f = plant::figure_spc(n.name, std::move(*v), b);
      if (!f) return std::fprintf(stderr, "%s\n", f.error().c_str()), 1;
      flagged += f->flagged_units.size();
      values += f->values.size();
      if (n.name == "d(T1)") one = std::chrono::duration<double>(Clock::now() - t1).count();
    }
    // The p-charts of marginal and fail verdicts per bench per month.
    auto verdicts = plant::verdict_values(*c, {});
    if (!verdicts) return std::fprintf(stderr, "%s\n", verdicts.error().message.c_str()), 1;
    flagged_benches.clear();
    for (const char* v : {"marginal", "fail"}) {
      plant::Baseline pb;
      pb.first_n = 2000;
      auto p = plant::proportion_chart(*verdicts, v, pb);
      if (!p) return std::fprintf(stderr, "%s\n", p.error().c_str()), 1;
      for (const auto& b : p->flagged_benches) flagged_benches += std::string(v) + ":" + b + " ";
    }
    best = std::min(best, std::chrono::duration<double>(Clock::now() - t0).count());
    best_one = std::min(best_one, one);
  }
  std::printf("fleet spc: every figure (%zu values) and the p-charts %.3f s, d(T1) alone %.3f s (best of 5); %zu units "
              "flagged; benches out of limits: %s\n",
              values, best, best_one, flagged, flagged_benches.empty() ? "none" : flagged_benches.c_str());
  return 0;
}
