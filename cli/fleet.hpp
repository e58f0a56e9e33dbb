// fogctl fleet: the plant store's queries (issue 14, docs/plant.md): serials, one serial's
// history, figures and their distributions by lot, bench or month, and control charts
// (`fleet spc`) with the Western Electric rules, flagged units, lot comparison and an HTML report.
//
// Only these commands need the PostgreSQL client (libpq and its ~22 libraries: Kerberos, LDAP,
// GnuTLS...), so they run in a program of their own, fogctl-fleet (fleet_main.cpp, library
// fogbench_cli_fleet): fogctl defines the commands and their options (its --help, man page and
// completion list them) and, once a fleet command is parsed, executes fogctl-fleet with the same
// arguments (fleet_exec.cpp); every other command starts without loading libpq (issue 30).
#pragma once

#include <cstdint>
#include <functional>
#include <iosfwd>
#include <optional>
#include <string>
#include <vector>

#include "common.hpp"
#include "fogbench/plant/fleet.hpp"

namespace CLI {
class App;
}

namespace fogbench::cli {

struct FleetOptions {
  std::string db;       // --db: a libpq connection string or URI
  std::string service;  // --service: a name in pg_service.conf
  plant::FleetFilter filter;
  bool json = false;
  std::string serial;                // serial (history)
  std::vector<std::string> figures;  // dist, spc (default: every figure present)
  std::string by = "lot";            // dist
  std::optional<std::size_t> baseline_n;
  std::optional<std::string> baseline_from, baseline_to;
  std::string compare;  // "LOT_A,LOT_B"
  double level = 0.95;
  std::string html;     // spc: the report's file
  std::string period = "month";            // spc: the p-charts' period (month, week, day)
  std::optional<std::size_t> p_baseline_n; // spc: the p-charts' limits from the first N verdicts (2000)
  // generate: a demonstration plant (plant/generate.hpp) on benches gen-bench-1..N; what those
  // benches held before is replaced, nothing of any other bench is touched.
  int gen_runs = 400, gen_units_per_run = 2, gen_lots = 8, gen_benches = 4, gen_outliers = 5;
  int gen_sample_runs = 0;        // the first N runs also get samples (the charts read none)
  int gen_samples_per_unit = 1000; // ... this many per unit, 1 s apart
  std::uint64_t gen_seed = 1;
};

// command: serials | serial (alias history) | figures | dist | spc | generate. In fogbench_cli_fleet
// (links libpq).
int run_fleet(const std::string& command, const FleetOptions& o, std::ostream& out, std::ostream& err);

// What a parsed fleet command does: run_fleet in fogctl-fleet, run_fleet_program in fogctl.
using FleetRunner = std::function<int(const std::string& command, const FleetOptions& o)>;
// The `fleet` command and its subcommands with their options (fleet_command.cpp: no libpq).
void add_fleet_command(CLI::App& app, int& code, FleetRunner run);

// fogctl's runner: executes fogctl-fleet with fogctl's own arguments (argv[1..]), found beside
// the running fogctl (/proc/self/exe: the build tree's bin/) or at the installed place
// (bin/../libexec/fogbench/fogctl-fleet). Returns only when it cannot be executed: prints why,
// naming the paths tried, and returns kExitError.
int run_fleet_program(char** argv, std::ostream& err);
// The paths tried, in order, for the fogctl at `self` (the running executable's path).
std::vector<std::string> fleet_program_candidates(const std::string& self);

}  // namespace fogbench::cli
