// The daemon's one mapping of store and model failures to protocol codes (api.hpp).
#include <catch2/catch.hpp>

#include "fogbench/daemon/api.hpp"

using namespace fogbench;
using namespace fogbench::daemon;
using C = model::FitError::Code;

TEST_CASE("api: a fit error's code depends on the failure, not on the command") {
  // What the request asked for is invalid: bad_request.
  CHECK(code_of(C::bad_options) == ErrorCode::bad_request);
  CHECK(code_of(C::bad_term) == ErrorCode::bad_request);
  // The run's data cannot carry the analysis: internal ("analysis failed").
  for (C c : {C::too_short, C::missing_signal, C::collinear, C::degenerate, C::uneven_time}) {
    INFO(model::to_string(c));
    CHECK(code_of(c) == ErrorCode::internal);
  }
  const ApiError e = from_fit("compare failed", model::FitError{C::too_short, "run 2: 20 samples"});
  CHECK(e.code == ErrorCode::internal);
  CHECK(e.message == "compare failed (too_short): run 2: 20 samples");
}

TEST_CASE("api: a store error is not_found for what is not there, else internal with the store's code") {
  CHECK(from_store({storage::StoreErrc::not_found, 0, "run 9"}).code == ErrorCode::not_found);
  const ApiError full = from_store({storage::StoreErrc::disk_full, 0, "no room"});
  CHECK(full.code == ErrorCode::internal);
  CHECK(full.message == "disk_full: no room");
}
