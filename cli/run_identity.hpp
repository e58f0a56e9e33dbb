// A run's identity on fogctl's side (issue 13): run get's table of it, the `# key: value`
// comment lines at the top of an exported CSV, and the report header's lines read back from a
// CSV file (docs/daemon.md "Run identity", docs/csv.md).
#pragma once

#include <optional>
#include <ostream>
#include <string>

#include <nlohmann/json.hpp>

#include "fogbench/storage/identity.hpp"

namespace fogbench::cli {

// run.get's `identity` object back into the store's value; empty for null.
std::optional<storage::RunIdentity> identity_from_json(const nlohmann::json& identity);
// The CSV export's header comment of unit `unit` of run.get's reply ("" when it has no identity).
std::string identity_csv_comments(const nlohmann::json& run_get, int unit);
// run get's lines: station, operator, software, hashes, and per unit its power-on.
void print_identity(const nlohmann::json& identity, std::ostream& out);
// Who decided a verdict (run.get's `verdicts` entry, a certificate's `qualification`):
// "plan NAME (plan ID)" or "analysis settings".
std::string verdict_by_text(const nlohmann::json& verdict);
// The identity fields in the comments atop a CSV file (empty when none or unreadable).
std::vector<std::pair<std::string, std::string>> csv_file_identity(const std::string& path);

}  // namespace fogbench::cli
