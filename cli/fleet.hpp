// fogctl fleet: the plant store's queries (issue 14, docs/plant.md): serials, one serial's
// history, figures and their distributions by lot, bench or month, and control charts
// (`fleet spc`) with the Western Electric rules, flagged units, lot comparison and an HTML report.
#pragma once

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
};

// command: serials | serial (alias history) | figures | dist | spc.
int run_fleet(const std::string& command, const FleetOptions& o, std::ostream& out, std::ostream& err);
void add_fleet_command(CLI::App& app, int& code);

}  // namespace fogbench::cli
