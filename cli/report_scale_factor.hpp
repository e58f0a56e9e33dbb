// The report's scale-factor section (issue 29, point 2): a rate-sequence run's scale factor
// over temperature (model::sf::fit, docs/scale-factor.md) as a page shows it: the temperature
// sensitivity and the firmware's model form, a table per plateau, the scale factor's deviation
// against the coil temperature with the model form drawn through it, and each plateau's
// nonlinearity (the step means' residuals from its least-squares line) against the input rate.
#pragma once

#include <cstddef>
#include <nlohmann/json.hpp>
#include <string>

#include "fogbench/model/scale_factor.hpp"

namespace fogbench::cli::report_html {

// The section's HTML; its two plots' specs appended to `specs` (ids "sf_temp", "sf_nl").
// `source` names the file it was read from, `coil_column` the temperature it used.
std::string scale_factor_section(const model::sf::Result& r, const std::string& source, const std::string& coil_column,
                                 nlohmann::json& specs, std::size_t max_points);

}  // namespace fogbench::cli::report_html
