// fogctl fleet spc: the proportion charts of verdicts (plant/verdicts.hpp) as JSON, a table and
// an HTML section.
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "fogbench/plant/verdicts.hpp"

namespace fogbench::cli {

nlohmann::json proportion_json(const plant::ProportionChart& ch);
std::string proportion_text(const plant::ProportionChart& ch);
// proportions: an array of proportion_json's.
std::string proportion_html(const nlohmann::json& proportions);

}  // namespace fogbench::cli
