// bench_plant_generate: fills a plant store with a generated fleet (plant/generate.hpp) and
// times `fleet spc` over it (every figure: query, chart, rules), the issue 14 figure (< 1 s).
//   bench_plant_generate --db "host=/tmp/pg port=5433 user=postgres dbname=postgres" [--runs 10000]
//                        [--sample-runs 100] [--no-generate]
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <string>

#include "fogbench/plant/fleet_spc.hpp"
#include "fogbench/plant/generate.hpp"

using namespace fogbench;
using Clock = std::chrono::steady_clock;

int main(int argc, char** argv) {
  std::string db;
  plant::GenerateOptions o;
  o.sample_runs = 100;
  bool generate = true;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--db" && i + 1 < argc) db = argv[++i];
    else if (a == "--runs" && i + 1 < argc) o.runs = std::stoi(argv[++i]);
    else if (a == "--sample-runs" && i + 1 < argc) o.sample_runs = std::stoi(argv[++i]);
    else if (a == "--no-generate") generate = false;
    else {
      std::fprintf(stderr, "usage: bench_plant_generate --db CONNSTR [--runs N] [--sample-runs N] [--no-generate]\n");
      return 2;
    }
  }
  if (db.empty()) return std::fprintf(stderr, "bench_plant_generate: --db is required\n"), 2;
  auto c = plant::Connection::open(db, true);
  if (!c) return std::fprintf(stderr, "%s\n", c.error().message.c_str()), 1;
  if (generate) {
    const auto t0 = Clock::now();
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
    best = std::min(best, std::chrono::duration<double>(Clock::now() - t0).count());
    best_one = std::min(best_one, one);
  }
  std::printf("fleet spc: every figure (%zu values) %.3f s, d(T1) alone %.3f s (best of 5); %zu units flagged\n",
              values, best, best_one, flagged);
  return 0;
}
