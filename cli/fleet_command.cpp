// fogctl fleet's commands and options (fleet.hpp), without the queries: fogctl defines them for its
// --help, man page and completion, and fogctl-fleet for running them.
#include <CLI/CLI.hpp>

#include "fleet.hpp"

namespace fogbench::cli {

void add_fleet_command(CLI::App& app, int& code, FleetRunner run) {
  static FleetOptions o;
  auto* f = app.add_subcommand("fleet", "The plant store (PostgreSQL): serials, histories, distributions and control charts across benches and lots");
  f->require_subcommand(1);
  auto common = [](CLI::App* s) {
    s->add_option("--db", o.db, "The plant store: a libpq connection string or URI (\"host=... dbname=plant\")");
    s->add_option("--service", o.service, "The plant store by its name in pg_service.conf");
    s->add_option("--lot", o.filter.lot, "Only units of this lot");
    s->add_option("--bench", o.filter.bench, "Only runs of this bench");
    s->add_option("--serial", o.filter.serial, "Only this serial");
    s->add_option("--since", o.filter.since, "Only runs that ended at or after this time (ISO 8601, e.g. 2026-01-01)");
    s->add_option("--until", o.filter.until, "Only runs that ended before this time (ISO 8601)");
    s->add_flag("--json", o.json, "Print JSON instead of tables");
  };
  auto* s = f->add_subcommand("serials", "Every serial with its runs, lots, benches and last verdict");
  common(s);
  s->callback([&code, run] { code = run("serials", o); });
  auto* h = f->add_subcommand("serial",
                              "One serial's history: its runs across benches with their identity (station, operator, "
                              "software, config and profile hashes), lot, verdict and figures, and its certificates");
  h->alias("history");
  common(h);
  h->add_option("serial", o.serial, "The serial")->required();
  h->callback([&code, run] { code = run("serial", o); });
  auto* g = f->add_subcommand("figures", "The figures stored: model coefficients and verdict figures, with counts");
  common(g);
  g->callback([&code, run] { code = run("figures", o); });
  auto* d = f->add_subcommand("dist", "A figure's distribution by lot, bench or month");
  common(d);
  d->add_option("--figure", o.figures, "The figure (repeatable; default every figure)");
  d->add_option("--by", o.by, "Group by lot, bench or month (default lot)");
  d->callback([&code, run] { code = run("dist", o); });
  auto* c = f->add_subcommand("spc", "Individuals and moving-range charts, Western Electric rules, flagged units, lot comparison, p-charts of marginal and fail verdicts per bench");
  common(c);
  c->add_option("--figure", o.figures, "The figure (repeatable; default every figure)");
  c->add_option("--baseline", o.baseline_n, "Limits from the first N values (default 100)");
  c->add_option("--baseline-from", o.baseline_from, "Limits from runs that ended at or after this time (ISO 8601)");
  c->add_option("--baseline-to", o.baseline_to, "... and before this time");
  c->add_option("--compare", o.compare, "Compare two lots, LOT_A,LOT_B: difference of means with its interval (Welch)");
  c->add_option("--level", o.level, "The comparison interval's level (default 0.95)");
  c->add_option("--html", o.html, "Also write the charts as an HTML report to this file");
  c->add_option("--period", o.period, "The p-charts' period: month (default), week or day");
  c->add_option("--p-baseline", o.p_baseline_n,
                "The p-charts' limits from the first N verdicts (default 2000; --baseline-from/--baseline-to apply too)");
  c->callback([&code, run] { code = run("spc", o); });
  auto* gen = f->add_subcommand("generate",
                              "Fill the plant store with a demonstration plant on benches gen-bench-1..N (one lot shifted, outlier units, "
                              "a bench with extra marginal verdicts), replacing only what those benches held");
  gen->add_option("--db", o.db, "The plant store: a libpq connection string or URI (\"host=... dbname=plant\")");
  gen->add_option("--service", o.service, "The plant store by its name in pg_service.conf");
  gen->add_option("--runs", o.gen_runs, "Runs to generate (default 400)");
  gen->add_option("--units-per-run", o.gen_units_per_run, "Units (serials) per run (default 2)");
  gen->add_option("--lots", o.gen_lots, "Lots, consecutive runs each (default 8); the one two thirds in is shifted by 1 sigma in d(T1)");
  gen->add_option("--benches", o.gen_benches, "Benches the runs go to in turn (default 4)");
  gen->add_option("--outliers", o.gen_outliers, "Units planted 6 sigma away in d(T1) (default 5)");
  gen->add_option("--sample-runs", o.gen_sample_runs, "The first N runs also get samples (default 0: the charts read none)");
  gen->add_option("--samples-per-unit", o.gen_samples_per_unit, "Samples per unit of those runs, 1 s apart (default 1000)");
  gen->add_option("--seed", o.gen_seed, "The random seed (default 1): the same seed, the same plant");
  gen->add_flag("--json", o.json, "Print JSON instead of a table");
  gen->callback([&code, run] { code = run("generate", o); });
}

}  // namespace fogbench::cli
