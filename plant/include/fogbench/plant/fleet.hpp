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

// The identity a run was recorded with (issue 13, docs/storage.md), as replicated.
struct RunIdentityInfo {
  std::string station_id, operator_name, operator_source, software_version, git_hash, config_sha256, profile_sha256;
};

struct HistoryEntry {
  std::string bench;
  std::int64_t run_id = 0;
  int unit_index = 0;
  std::optional<std::string> lot, ended_at, verdict;
  std::string purpose, state;
  std::vector<std::pair<std::string, double>> figures;  // by source then name
  std::optional<RunIdentityInfo> identity;               // none for a run recorded without one
  std::optional<std::string> powered_on_at;              // the unit's power-on (ISO 8601 UTC), when seen
  std::optional<double> since_power_on_s;                // s from it to the run's creation
};
PlantResult<std::vector<HistoryEntry>> serial_history(Connection& c, const std::string& serial, const FleetFilter& f);

// A certificate issued for a serial, as replicated with that serial's runs.
struct SerialCertificate {
  std::string bench;
  std::int64_t certificate_id = 0, model_id = 0;
  int model_version = 0;
  std::string sha256;
  std::optional<std::string> issued_at;  // ISO 8601 UTC
  std::optional<std::string> verdict;    // the certificate's own "verdict" field
  std::optional<std::int64_t> run_id;    // the run the certified model was fitted on, when the plant holds it
};
// In the order issued (then bench, id). Filters by bench only (a certificate has no lot or run end).
PlantResult<std::vector<SerialCertificate>> serial_certificates(Connection& c, const std::string& serial,
                                                                const FleetFilter& f);

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
