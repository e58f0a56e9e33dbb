// The run reads of the socket protocol (docs/protocol.md run.list, run.get, run.samples): a
// stored run, its models, samples and verdicts as the replies show them. Used by the command
// handler (handler.cpp); they read through the Store they are given (the worker's read
// connection for the offloaded run.get and run.samples).
#pragma once

#include <cstdint>
#include <string>

#include <nlohmann/json.hpp>

#include "fogbench/daemon/api.hpp"
#include "fogbench/storage/models.hpp"
#include "fogbench/storage/runs.hpp"
#include "fogbench/storage/samples.hpp"
#include "fogbench/storage/store.hpp"

namespace fogbench::daemon {

nlohmann::json run_json(const storage::RunRecord& r);
// The stored text as JSON, or as a string when it is not JSON.
nlohmann::json parse_or_string(const std::string& text);
nlohmann::json model_json(const storage::ModelRecord& m);
// A stored row as run.samples sends it; a unit of 3 axes (storage::RunUnit::axes) with its y and z.
nlohmann::json sample_json(const storage::SampleRow& r, int axes = 1);
// `unit` is an index into the run's units or a serial; absent means the first unit.
ApiResult<int> resolve_unit(storage::Store& store, std::int64_t run_id, const nlohmann::json& req);
// The same, as the run's unit record (its index, serial and axes).
ApiResult<storage::RunUnit> resolve_run_unit(storage::Store& store, std::int64_t run_id, const nlohmann::json& req);
// run.get: `end` and `live_quality` are what the station knows and the store may not yet.
ApiResult<nlohmann::json> run_get(storage::Store& store, std::int64_t run_id, const nlohmann::json& end,
                                  const nlohmann::json& live_quality);
// run.samples: a page of [offset, offset + limit) of the unit's samples, with the total.
ApiResult<nlohmann::json> run_samples(storage::Store& store, std::int64_t run_id, const nlohmann::json& req,
                                      std::int64_t offset, std::int64_t limit);

}  // namespace fogbench::daemon
