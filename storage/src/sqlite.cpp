// The SQLite helpers of the store: error mapping, statement cache, queries, transactions.
#include "sqlite.hpp"

#include "fogbench/storage/run_data.hpp"

#include <cassert>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <limits>

namespace fogbench::storage::detail {

StoreErrc code_of(int sqlite_rc) {
  switch (sqlite_rc & 0xff) {  // the primary code of an extended one
    case SQLITE_FULL: return StoreErrc::disk_full;
    case SQLITE_READONLY: return StoreErrc::read_only;
    case SQLITE_IOERR: return StoreErrc::io;
    case SQLITE_BUSY:
    case SQLITE_LOCKED: return StoreErrc::busy;
    case SQLITE_CORRUPT:
    case SQLITE_NOTADB: return StoreErrc::corrupt;
    case SQLITE_CONSTRAINT: return StoreErrc::constraint;
    case SQLITE_CANTOPEN: return StoreErrc::open_failed;
    default: return StoreErrc::sqlite;
  }
}

Database::Database(sqlite3* db, std::filesystem::path path, OpenOptions options)
    : db_(db), path_(std::move(path)), options_(std::move(options)) {}

Database::~Database() {
  for (auto& [sql, stmt] : cache_) sqlite3_finalize(stmt);
  // Every statement is finalized, so close cannot fail with SQLITE_BUSY; the last connection
  // to a WAL database checkpoints it here.
  sqlite3_close(db_);
}

StoreError Database::error(int rc, std::string_view what) const {
  StoreError e;
  e.code = code_of(rc);
  e.sqlite_code = rc;
  // errmsg describes the last failed call on this connection, which is the one that returned
  // rc; errstr is the fallback when a later call has overwritten it.
  const int last = sqlite3_extended_errcode(db_);
  const char* detail = last == rc ? sqlite3_errmsg(db_) : sqlite3_errstr(rc);
  e.message = std::string(what) + " in '" + path_.string() + "': " + detail;
  return e;
}

StoreError Database::error(StoreErrc code, std::string_view what) const {
  StoreError e;
  e.code = code;
  e.message = std::string(what) + " in '" + path_.string() + "'";
  return e;
}

StoreResult<sqlite3_stmt*> Database::statement(std::string_view sql) {
  if (auto it = cache_.find(sql); it != cache_.end()) return it->second;
  sqlite3_stmt* stmt = nullptr;
  const int rc = sqlite3_prepare_v3(db_, sql.data(), static_cast<int>(sql.size()),
                                    SQLITE_PREPARE_PERSISTENT, &stmt, nullptr);
  if (rc != SQLITE_OK) return std::unexpected(error(rc, "prepare '" + std::string(sql) + "'"));
  cache_.emplace(sql, stmt);
  return stmt;
}

StoreResult<void> Database::exec(const std::string& sql, std::string_view what) {
  const int rc = sqlite3_exec(db_, sql.c_str(), nullptr, nullptr, nullptr);
  if (rc != SQLITE_OK) return std::unexpected(error(rc, what));
  return {};
}

std::string Database::now_iso() const {
  return iso8601_utc(options_.clock ? options_.clock() : std::chrono::system_clock::now(), /*milliseconds=*/true);
}

Query::~Query() {
  sqlite3_reset(stmt_);
  sqlite3_clear_bindings(stmt_);
}

// Binding fails only for an index out of range or a value over SQLite's limits: both bugs
// here (the SQL is fixed and lengths are bounded by std::string), hence the asserts.
Query& Query::bind(int i, std::int64_t v) {
  [[maybe_unused]] int rc = sqlite3_bind_int64(stmt_, i, v);
  assert(rc == SQLITE_OK);
  return *this;
}

Query& Query::bind(int i, double v) {
  if (std::isnan(v)) return bind_null(i);
  [[maybe_unused]] int rc = sqlite3_bind_double(stmt_, i, v);
  assert(rc == SQLITE_OK);
  return *this;
}

Query& Query::bind(int i, std::string_view v) {
  // SQLite copies the text: callers bind temporaries (now_iso()), and no sample column is
  // text, so the copy costs nothing that matters. An empty view may have a null data(); that
  // would bind NULL, not ''.
  [[maybe_unused]] int rc = sqlite3_bind_text64(stmt_, i, v.empty() ? "" : v.data(), v.size(),
                                                SQLITE_TRANSIENT, SQLITE_UTF8);
  assert(rc == SQLITE_OK);
  return *this;
}

Query& Query::bind_null(int i) {
  [[maybe_unused]] int rc = sqlite3_bind_null(stmt_, i);
  assert(rc == SQLITE_OK);
  return *this;
}

double Query::real(int col) const {
  if (is_null(col)) return std::numeric_limits<double>::quiet_NaN();
  return sqlite3_column_double(stmt_, col);
}

std::string Query::text(int col) const {
  const auto* p = sqlite3_column_text(stmt_, col);
  const int n = sqlite3_column_bytes(stmt_, col);
  return p ? std::string(reinterpret_cast<const char*>(p), static_cast<std::size_t>(n))
           : std::string();
}

std::optional<std::string> Query::opt_text(int col) const {
  if (is_null(col)) return std::nullopt;
  return text(col);
}

std::optional<std::int64_t> Query::opt_int64(int col) const {
  if (is_null(col)) return std::nullopt;
  return int64(col);
}

std::optional<double> Query::opt_real(int col) const {
  if (is_null(col)) return std::nullopt;
  return sqlite3_column_double(stmt_, col);
}

namespace {
std::int64_t file_bytes(const std::filesystem::path& p) {
  std::error_code ec;
  const auto n = std::filesystem::file_size(p, ec);
  return ec ? 0 : static_cast<std::int64_t>(n);
}
}  // namespace

bool Database::checkpoint_truncate() {
  sqlite3_busy_timeout(db_, 0);  // a reader now: try again at the next write, never wait on the loop
  const int rc = sqlite3_wal_checkpoint_v2(db_, nullptr, SQLITE_CHECKPOINT_TRUNCATE, nullptr, nullptr);
  sqlite3_busy_timeout(db_, busy_timeout_ms);
  return rc == SQLITE_OK;
}

StoreResult<void> Database::keep_wal_within_limit(std::string_view what) {
  if (size_limit_bytes <= 0 || wal_budget_bytes <= 0) return {};
  const std::filesystem::path wal = path_.string() + "-wal";
  std::int64_t wal_bytes = file_bytes(wal);
  if (wal_bytes <= wal_budget_bytes / 2) return {};
  if (checkpoint_truncate()) wal_bytes = file_bytes(wal);
  if (wal_bytes <= wal_budget_bytes) return {};
  return std::unexpected(error(StoreErrc::disk_full,
                               std::string(what) + ": the store is full: its write-ahead log (" +
                                   std::to_string(wal_bytes) + " bytes) is over its share of the size limit (" +
                                   std::to_string(wal_budget_bytes) +
                                   " bytes) and a reader keeps it from being checkpointed"));
}

Transaction::~Transaction() {
  // After SQLITE_FULL or an I/O error SQLite may have rolled back already (autocommit again).
  if (open_ && !sqlite3_get_autocommit(db_.handle()))
    sqlite3_exec(db_.handle(), "ROLLBACK", nullptr, nullptr, nullptr);
}

StoreResult<void> Transaction::begin(std::string_view what) {
  assert(!open_);
  if (auto ok = db_.keep_wal_within_limit(what); !ok) return ok;
  auto stmt = db_.statement("BEGIN IMMEDIATE");
  if (!stmt) return std::unexpected(stmt.error());
  Query q(db_, *stmt);
  if (int rc = q.step(); rc != SQLITE_DONE) return std::unexpected(db_.error(rc, what));
  open_ = true;
  return {};
}

StoreResult<void> Transaction::commit(std::string_view what) {
  assert(open_);
  auto stmt = db_.statement("COMMIT");
  if (!stmt) return std::unexpected(stmt.error());
  Query q(db_, *stmt);
  if (int rc = q.step(); rc != SQLITE_DONE) return std::unexpected(db_.error(rc, what));
  open_ = false;
  return {};
}

}  // namespace fogbench::storage::detail
