// The daemon's failures as the protocol says them: an error code (fogbench::protocol) and a
// message, and the one mapping from each library's failures to those codes, so that the same
// failure gets the same code whichever command meets it.
#pragma once

#include <expected>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "fogbench/model/model.hpp"
#include "fogbench/protocol/protocol.hpp"
#include "fogbench/storage/errors.hpp"

namespace fogbench::daemon {

using protocol::ErrorCode;
using protocol::to_string;

struct ApiError {
  ErrorCode code;
  std::string message;
};
template <class T>
using ApiResult = std::expected<T, ApiError>;

inline std::unexpected<ApiError> api_error(ErrorCode c, std::string message) {
  return std::unexpected(ApiError{c, std::move(message)});
}

// A store failure: `not_found` for a run, model or unit that is not there, else `internal`
// (the message starts with the store's own code, e.g. "disk_full: ...").
ApiError from_store(const storage::StoreError& e);

// A failed fit, verification or workbench step, `what` naming it ("fit failed", "compare
// failed"), and the model's code in parentheses. One mapping for every command:
//   bad_options, bad_term -> bad_request: what the request asked for is not valid (an unknown
//     term, a term the model has already, an option out of range);
//   too_short, missing_signal, collinear, degenerate, uneven_time -> internal: the run's data
//     cannot carry the analysis ("storage or analysis failed", docs/protocol.md).
ErrorCode code_of(model::FitError::Code c);
ApiError from_fit(const char* what, const model::FitError& e);

// A request's `units`: an array of serials, each a storable name (storage::check_stored_text,
// at most 64 bytes, no control characters), else a bad_request naming the field (`units`,
// `units[1]`). Absent: an error when `required`, else no serials. run.start, plan.* and
// queue.add read them through this one check.
ApiResult<std::vector<std::string>> serials_field(const nlohmann::json& req, bool required);

}  // namespace fogbench::daemon
