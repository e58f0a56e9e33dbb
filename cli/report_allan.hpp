// The report's Allan section of one run (issue 13, point 5): the overlapping Allan deviation of
// each hold and of the compensated output (the series of fogctl allan, allan.hpp), drawn
// log-log with the -1/2 (angle random walk) and +1/2 (rate random walk) slopes, and the noise
// terms of IEEE Std 952 Annex C with their 1-sigma intervals in a table.
#pragma once

#include <cstddef>
#include <nlohmann/json.hpp>
#include <string>

#include "fogbench/model/allan.hpp"
#include "fogbench/model/model.hpp"

namespace fogbench::cli::report_html {

// Series shorter than this are not analysed (10 min at 1 Hz, fogctl allan's default).
inline constexpr std::size_t kAllanMinSamples = 600;

// The section's HTML (its plot's spec appended to `specs`, id "allan" + key).
std::string allan_section(const model::Model& m, const model::RunData& run, const std::string& key, nlohmann::json& specs,
                          std::size_t max_points);

// A noise estimate as the section's table writes it: "value (low..high)" with `digits`
// decimals, "-" when the curve does not show the term.
std::string allan_cell(const std::optional<model::allan::NoiseEstimate>& e, int digits);

}  // namespace fogbench::cli::report_html
