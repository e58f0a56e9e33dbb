// The thin layer over SQLite's C API that the store is written in: a connection with its
// statement cache, a statement in use, and a write transaction. Internal to storage.
#pragma once

#include <sqlite3.h>

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <unordered_map>

#include "fogbench/storage/store.hpp"

namespace fogbench::storage::detail {

StoreErrc code_of(int sqlite_rc);

// One connection. Owns the sqlite3 handle and every statement prepared on it.
class Database {
 public:
  Database(sqlite3* db, std::filesystem::path path, OpenOptions options);
  ~Database();
  Database(const Database&) = delete;
  Database& operator=(const Database&) = delete;

  sqlite3* handle() const { return db_; }
  const std::filesystem::path& path() const { return path_; }
  const OpenOptions& options() const { return options_; }
  int version = 0;  // the schema version, once opened
  // OpenOptions::size_limit_bytes in pages (0: no limit), and the last pages of it kept for the
  // audit trail: samples may not use them (see with_reserve in store.cpp).
  std::int64_t limit_pages = 0;
  std::int64_t reserve_pages = 0;
  // OpenOptions::size_limit_bytes (0: none) and the write-ahead log's share of it.
  std::int64_t size_limit_bytes = 0;
  std::int64_t wal_budget_bytes = 0;
  // With a size limit, before each write transaction: checkpoints the WAL back to nothing when
  // it holds over half its share, and refuses the write (disk_full) when it is over its share
  // and a reader keeps it from being checkpointed.
  StoreResult<void> keep_wal_within_limit(std::string_view what);
  // PRAGMA wal_checkpoint(TRUNCATE) without waiting for readers; false when one held it.
  bool checkpoint_truncate();
  int busy_timeout_ms = 0;  // as set on the connection

  // The failure of the call that just returned `rc`, with what was being done.
  StoreError error(int rc, std::string_view what) const;
  // A failure found by the store itself (not_found, invalid_argument...).
  StoreError error(StoreErrc code, std::string_view what) const;

  // A prepared statement, compiled on first use and kept. `sql` must have static storage
  // duration: it is the cache key.
  StoreResult<sqlite3_stmt*> statement(std::string_view sql);
  // Runs SQL that returns no rows, uncached (schema scripts, pragmas).
  StoreResult<void> exec(const std::string& sql, std::string_view what);
  // The current time as ISO 8601 UTC with milliseconds, from OpenOptions::clock.
  std::string now_iso() const;

 private:
  sqlite3* db_;
  std::filesystem::path path_;
  OpenOptions options_;
  std::unordered_map<std::string_view, sqlite3_stmt*> cache_;
};

// A cached statement being used: bind, step, read columns. Resets the statement and clears
// its bindings when it goes out of scope, so the cache never holds a half-used statement.
class Query {
 public:
  Query(Database& db, sqlite3_stmt* stmt) : db_(db), stmt_(stmt) {}
  ~Query();
  Query(const Query&) = delete;
  Query& operator=(const Query&) = delete;

  Query& bind(int i, std::int64_t v);
  Query& bind(int i, int v) { return bind(i, static_cast<std::int64_t>(v)); }
  Query& bind(int i, double v);  // NaN binds NULL: a value not read
  Query& bind(int i, std::string_view v);
  Query& bind_null(int i);
  template <class T>
  Query& bind(int i, const std::optional<T>& v) {
    return v ? bind(i, *v) : bind_null(i);
  }

  // SQLITE_ROW, SQLITE_DONE or an error code.
  int step() { return sqlite3_step(stmt_); }
  // Ready for the next row of a bulk insert; keeps the bindings.
  void reset() { sqlite3_reset(stmt_); }

  bool is_null(int col) const { return sqlite3_column_type(stmt_, col) == SQLITE_NULL; }
  std::int64_t int64(int col) const { return sqlite3_column_int64(stmt_, col); }
  double real(int col) const;  // NULL reads as NaN
  std::string text(int col) const;
  std::optional<std::string> opt_text(int col) const;
  std::optional<std::int64_t> opt_int64(int col) const;
  std::optional<double> opt_real(int col) const;

 private:
  Database& db_;
  sqlite3_stmt* stmt_;
};

// BEGIN IMMEDIATE ... COMMIT: takes the write lock up front, so a transaction never fails
// half-way on a lock upgrade. Rolls back when destroyed uncommitted.
class Transaction {
 public:
  explicit Transaction(Database& db) : db_(db) {}
  ~Transaction();
  Transaction(const Transaction&) = delete;
  Transaction& operator=(const Transaction&) = delete;

  StoreResult<void> begin(std::string_view what);
  StoreResult<void> commit(std::string_view what);

 private:
  Database& db_;
  bool open_ = false;
};

}  // namespace fogbench::storage::detail
