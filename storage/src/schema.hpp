// The store's schema: the ordered migration scripts and the checks made when a file is opened.
// Internal to storage; docs/storage.md describes the tables.
#pragma once

#include <cstdint>
#include <span>
#include <string_view>

#include "sqlite.hpp"

namespace fogbench::storage::detail {

// Written to the file header (PRAGMA application_id): "FOGB". Tells a fogbench store from any
// other SQLite database.
inline constexpr std::int32_t kApplicationId = 0x464F4742;

struct Migration {
  int version;           // user_version after the script has run
  std::string_view what;
  const char* sql;
};

// In order; migration i takes a database from version i to i + 1. Never edit a published
// script: add a new one.
std::span<const Migration> migrations();
int current_version();

// Reads the header and refuses a file that is not a fogbench store or is newer than this
// build. Writes nothing. Returns the file's schema version (0 for a new, empty file).
StoreResult<int> inspect_schema(Database& db);

// Runs the missing migrations, each in its own transaction with its user_version, so a
// failure leaves the file at the last complete version. Safe against another process
// migrating the same file at the same time.
StoreResult<int> migrate(Database& db, int from_version);

}  // namespace fogbench::storage::detail
