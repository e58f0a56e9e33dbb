// The fleet queries over the plant store (issue 14, `fogctl fleet`): serials, one serial's
// history, and a figure's values in time order for the statistics of spc.hpp. Every filter is
// optional and passed as a parameter (never spliced into SQL).
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "fogbench/plant/plant.hpp"

namespace fogbench::plant {

struct FleetFilter {
  std::optional<std::string> lot, bench, serial;
  std::optional<std::string> since, until;  // ISO 8601 dates or times: the run's end in [since, until)
};

struct SerialSummary {
  std::string serial;
  std::int64_t runs = 0;
  std::string lots, benches;                 // distinct, comma-separated
  std::optional<std::string> first_at, last_at;  // run ends, ISO 8601 UTC
  std::optional<std::string> last_verdict;
};
PlantResult<std::vector<SerialSummary>> serials(Connection& c, const FleetFilter& f);

struct HistoryEntry {
  std::string bench;
  std::int64_t run_id = 0;
  int unit_index = 0;
  std::optional<std::string> lot, ended_at, verdict;
  std::string purpose, state;
  std::vector<std::pair<std::string, double>> figures;  // by source then name
};
PlantResult<std::vector<HistoryEntry>> serial_history(Connection& c, const std::string& serial, const FleetFilter& f);

// One unit's value of one figure ("T1", "mu0", "ratio", ...), with where it came from.
struct FigureValue {
  std::string bench;
  std::int64_t run_id = 0;
  int unit_index = 0;
  std::string serial;
  std::optional<std::string> lot, ended_at;
  std::string source;  // model | verification
  double value = 0;
};
// In the order the runs ended (then bench, run, unit).
PlantResult<std::vector<FigureValue>> figure_values(Connection& c, const std::string& name, const FleetFilter& f);
// The figure names present, with their source and count.
struct FigureName {
  std::string name, source;
  std::int64_t count = 0;
};
PlantResult<std::vector<FigureName>> figure_names(Connection& c, const FleetFilter& f);

}  // namespace fogbench::plant
