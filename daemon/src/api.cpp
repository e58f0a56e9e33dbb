// The daemon's one mapping of store and model failures to protocol codes (api.hpp).
#include "fogbench/daemon/api.hpp"

#include "fogbench/storage/identity.hpp"

namespace fogbench::daemon {

ApiError from_store(const storage::StoreError& e) {
  // A pruned run's samples are not here any more: not_found, with when and where they went.
  if (e.code == storage::StoreErrc::not_found || e.code == storage::StoreErrc::pruned)
    return {ErrorCode::not_found, e.message};
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

ApiResult<std::vector<std::string>> serials_field(const nlohmann::json& req, bool required) {
  std::vector<std::string> serials;
  if (!req.contains("units")) {
    if (required) return api_error(ErrorCode::bad_request, "units: missing");
    return serials;
  }
  const nlohmann::json& units = req["units"];
  if (!units.is_array()) return api_error(ErrorCode::bad_request, "units: expected an array of serials");
  for (const auto& u : units) {
    if (!u.is_string()) return api_error(ErrorCode::bad_request, "units: expected an array of serials");
    const std::string field = "units[" + std::to_string(serials.size()) + "]";
    if (auto why = storage::check_stored_text(field, u.get<std::string>(), storage::kMaxNameBytes); !why.empty())
      return api_error(ErrorCode::bad_request, why);
    serials.push_back(u.get<std::string>());
  }
  return serials;
}

}  // namespace fogbench::daemon
