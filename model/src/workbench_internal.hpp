// What diagnose's files share inside model/: one step of the search (diagnose_once, in
// workbench_diagnose.cpp) and the language's generated candidates (workbench_search.cpp).
#pragma once

#include <string>
#include <vector>

#include "fogbench/model/workbench.hpp"

namespace fogbench::model::workbench {

// Why a term cannot be evaluated on a run (Ta or ton not recorded), empty when it can.
std::string missing_signal_of(const Expr& e, const RunData& run);

namespace wbi {

// A candidate of the language search: the term (canonical, no lag) and what it would mean.
struct Generated {
  std::string expr, effect, explanation;
};

struct SearchStats {
  std::size_t scanned = 0;   // generated candidates lag-scanned
  std::size_t refitted = 0;  // candidates refitted and scored (library and generated)
};

// One step: the model's terms refitted on the fit run, every library candidate (and the
// generated ones, screened by their lag scan's gain to o.refit_top) refitted and scored.
std::expected<Diagnosis, FitError> diagnose_once(const Model& m, const RunData& fit_run, std::span<const RunData> held_out,
                                                 const DiagnoseOptions& o, const std::vector<Generated>& gen, SearchStats* stats);

}  // namespace wbi
}  // namespace fogbench::model::workbench
