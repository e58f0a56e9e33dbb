// Internal to storage: the identity's rows written inside another write's transaction
// (create_run, import_run), so a run never exists without the identity it was given.
#pragma once

#include <cstdint>
#include <string_view>

#include "fogbench/storage/identity.hpp"
#include "sqlite.hpp"

namespace fogbench::storage::detail {

StoreResult<void> insert_identity(Database& db, std::int64_t run_id, const RunIdentity& id, std::string_view what);

}  // namespace fogbench::storage::detail
