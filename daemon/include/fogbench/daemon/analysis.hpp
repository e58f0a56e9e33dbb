// The analysis of stored runs (fit, verify, and the workbench's compare, diagnose and add_term)
// in two halves, so that the long half runs off the event loop. `compute` reads the run and the
// model through the store it is given (fogbenchd's analysis worker passes its own read
// connection) and runs the model code; it returns a Commit, which stores what was computed (a
// model, a verification) through the loop's store and gives the reply's result. Compare and
// diagnose store nothing: their Commit only hands the result over.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "fogbench/daemon/config.hpp"
#include "fogbench/daemon/station.hpp"
#include "fogbench/model/run.hpp"
#include "fogbench/storage/store.hpp"

namespace fogbench::daemon::analysis {

// The second half: runs on the loop thread with the loop's store (the only one that writes).
using Commit = std::function<ApiResult<nlohmann::json>(storage::Store& writer)>;

// Fits the unit's model (terms, method empty: the configured ones). Its parent is the serial's
// current model when it is stored (looked up by the Commit, on the writer). `axis`: one axis of
// a three-axis unit (model::select_axis; the model carries it, the parent is that axis'
// current model); empty: the unit's x as a one-axis unit's.
ApiResult<Commit> fit(storage::Store& reader, const AnalysisConfig& config, std::int64_t run_id,
                      int unit_index, const std::string& terms, const std::string& method,
                      const std::string& created_at, std::optional<model::Axis> axis = std::nullopt);
// Verifies the unit against model_id, or the serial's current model when empty (of `axis` when
// given: that axis of a three-axis unit, its result stored with its `axis`).
ApiResult<Commit> verify(storage::Store& reader, const AnalysisConfig& config, std::int64_t run_id,
                         int unit_index, std::optional<std::int64_t> model_id,
                         std::optional<model::Axis> axis = std::nullopt);
ApiResult<Commit> compare(storage::Store& reader, std::int64_t run_id, int unit_index,
                          std::optional<std::int64_t> model_id);
ApiResult<Commit> diagnose(storage::Store& reader, std::int64_t run_id, int unit_index,
                           std::optional<std::int64_t> model_id, const std::vector<std::int64_t>& held_out_runs);
// The refined model is stored with the model it came from as its parent.
ApiResult<Commit> add_term(storage::Store& reader, std::int64_t run_id, int unit_index, const std::string& term,
                           std::optional<std::int64_t> model_id, const std::string& created_at);

}  // namespace fogbench::daemon::analysis
