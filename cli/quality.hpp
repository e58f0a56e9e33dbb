// The data-quality check before physics as fogctl runs it on every run a model command loads:
// what --quality check|clean|warn|off does with each sensor problem (docs/data-quality.md).
#pragma once

#include <expected>
#include <string>

#include "common.hpp"
#include "fogbench/model/quality.hpp"

namespace fogbench::cli {

// Runs model::assess_quality on a loaded run and applies the mode: the run (cleaned where the
// mode cleans) or the refusal, naming the file, each sensor, interval and what to do. retry,
// when not empty, is the command as the user gave it (e.g. "fogctl fit run.csv"): a time-unit
// refusal then names the whole command that reads the file.
std::expected<model::RunData, std::string> check_run_quality(model::RunData run, const std::string& path, const std::string& mode,
                                                             QualityLog* log, const std::string& retry = {});

// One flag as JSON, with the run and what was done ("refused", "cleaned", "warned").
nlohmann::json to_json(const model::QualityFlag& f, const std::string& run, const std::string& action);

// The identification warnings of a fitted model on its run, as `warning:` lines.
std::vector<std::string> identification_lines(const model::Model& m, const model::RunData& run);

}  // namespace fogbench::cli
