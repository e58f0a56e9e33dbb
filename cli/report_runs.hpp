// The report's analysis plots of one run (issue 10, point 5): the residual before and after
// each added term, the ACF of the prewhitened residual and its CCF with each regressor with
// their confidence bands (as MATLAB's resid), the residual against T1, and the drift-vs-T1 loop.
#pragma once

#include <cstddef>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "fogbench/model/workbench.hpp"

namespace fogbench::cli::report_html {

// Confidence level of the ACF and CCF bands: MATLAB resid's default, 99% (z = 2.576).
inline constexpr double kBandLevel = 0.99;
inline constexpr int kAcfLags = 60;    // ACF over lags 1..60 samples
inline constexpr int kCcfLags = 300;   // CCF over lags -300..300 samples

// A model of the lineage, with its label for legends ("1: + T1^2@0").
struct Step {
  const model::Model* model = nullptr;
  std::string label;
  bool saved = true;  // false: a diagnose step refitted for the report, not in any file
};
// The lineage of m, root first, labelled with each step's added terms; then the diagnose
// steps (`added`, as fit --add takes them) refitted on fit_run from m, kept in `owned`.
std::vector<Step> lineage_steps(const model::Model& m, const model::RunData& fit_run, const std::vector<std::string>& added,
                                std::vector<std::unique_ptr<model::Model>>& owned, std::vector<std::string>& notes);

struct RunContext {
  const model::Model& m;             // the report's model
  const model::RunData& run;
  const model::workbench::RunComparison& cmp;  // m against run
  const model::workbench::QualRun* qual = nullptr;
  std::string key;                   // suffix of the plots' ids
};
// The plots' HTML (specs appended to `specs`), in the order listed above.
std::string analysis_plots(const RunContext& c, const std::vector<Step>& steps, nlohmann::json& specs, std::size_t max_points);

}  // namespace fogbench::cli::report_html
