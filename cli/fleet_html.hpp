// fogctl fleet spc --html: the fleet's control charts as one self-contained HTML page (the
// report's vendored uPlot inline, so it opens offline).
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "fogbench/plant/fleet_spc.hpp"

namespace fogbench::cli {

// charts: the JSON of each chart as `fleet spc --json` prints it (limits, signals, comparison);
// proportions: its p-charts of verdicts (fleet_pchart.hpp), drawn as tables first.
std::string fleet_html(const std::vector<plant::FigureSpc>& figures, const nlohmann::json& charts,
                       const nlohmann::json& proportions);

}  // namespace fogbench::cli
