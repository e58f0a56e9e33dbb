// The data-quality check before physics as fogctl runs it on every run a model command loads:
// what --quality check|clean|warn|off does with each sensor problem (docs/data-quality.md).
#pragma once

#include <expected>
#include <string>
#include <vector>

#include "common.hpp"
#include "fogbench/model/quality.hpp"

namespace fogbench::cli {

// Runs model::assess_quality on a loaded run and applies the mode: the run (cleaned where the
// mode cleans) or the refusal, naming the file, each sensor, interval and what to do. retry,
// when not empty, is the command as the user gave it (e.g. "fogctl fit run.csv"): a time-unit
// refusal then names the whole command that reads the file.
std::expected<model::RunData, std::string> check_run_quality(model::RunData run, const std::string& path, const std::string& mode,
                                                             QualityLog* log, const std::string& retry = {});

// Runs a command treats as one gyro's (diagnose's fit and held-out runs, a lineage's runs): an
// error when their `# serial:` comment lines (docs/csv.md, the run's identity) name different
// gyros, naming each file and serial; with --quality warn or off, a warning line instead (in
// `warnings`). Runs without a serial line are not judged.
std::expected<void, std::string> check_one_gyro(const std::vector<std::string>& paths, const std::string& mode,
                                                std::vector<std::string>& warnings);

// One flag as JSON, with the run and what was done ("refused", "cleaned", "warned").
nlohmann::json to_json(const model::QualityFlag& f, const std::string& run, const std::string& action);

// The identification warnings of a fitted model on its run, as `warning:` lines.
std::vector<std::string> identification_lines(const model::Model& m, const model::RunData& run);

}  // namespace fogbench::cli
