// How a Store call fails: StoreErrc, StoreError and StoreResult<T> (store.hpp's return type).
#pragma once

#include <expected>
#include <string>
#include <string_view>

namespace fogbench::storage {

enum class StoreErrc {
  open_failed,       // the file cannot be opened or created
  not_fogbench,      // a SQLite database that is not a fogbench store
  schema_too_new,    // written by a newer fogbench: refused, never modified
  schema_too_old,    // opened read-only but it needs a migration
  migration_failed,  // a migration script failed; the database keeps its old version
  not_found,         // no such run, unit, model
  invalid_argument,  // a caller's value is unusable: bad JSON, unequal column lengths, NaN time
  constraint,        // a uniqueness or reference violated, e.g. a sample time stored twice
  read_only,         // SQLITE_READONLY: a read-only file, directory or connection
  disk_full,         // SQLITE_FULL: the disk (or OpenOptions::size_limit_bytes) is full
  io,                // SQLITE_IOERR
  busy,              // SQLITE_BUSY or SQLITE_LOCKED after the busy timeout
  corrupt,           // SQLITE_CORRUPT or SQLITE_NOTADB
  sqlite,            // any other SQLite failure
  pruned,            // the run's samples were deleted by Store::prune (its record stays)
};
std::string_view to_string(StoreErrc code);

struct StoreError {
  StoreErrc code = StoreErrc::sqlite;
  int sqlite_code = 0;  // SQLite's extended result code; 0 when the error is not SQLite's
  std::string message;  // what was being done, in which file, and SQLite's own message
};

template <class T>
using StoreResult = std::expected<T, StoreError>;

}  // namespace fogbench::storage
