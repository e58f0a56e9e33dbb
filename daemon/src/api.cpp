// The daemon's one mapping of store and model failures to protocol codes (api.hpp).
#include "fogbench/daemon/api.hpp"

namespace fogbench::daemon {

ApiError from_store(const storage::StoreError& e) {
  if (e.code == storage::StoreErrc::not_found) return {ErrorCode::not_found, e.message};
  return {ErrorCode::internal, std::string(storage::to_string(e.code)) + ": " + e.message};
}

ErrorCode code_of(model::FitError::Code c) {
  using C = model::FitError::Code;
  switch (c) {
    case C::bad_options:
    case C::bad_term: return ErrorCode::bad_request;
    case C::too_short:
    case C::missing_signal:
    case C::collinear:
    case C::degenerate:
    case C::uneven_time: return ErrorCode::internal;
  }
  return ErrorCode::internal;
}

ApiError from_fit(const char* what, const model::FitError& e) {
  return {code_of(e.code), std::string(what) + " (" + std::string(model::to_string(e.code)) + "): " + e.message};
}

}  // namespace fogbench::daemon
