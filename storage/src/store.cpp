// The Store API: opening, and every read and write of runs, samples, events, models and
// verifications, over the cached statements of sqlite.hpp.
#include "fogbench/storage/runs.hpp"
#include "fogbench/storage/store.hpp"

#include <algorithm>
#include <cassert>
#include <cerrno>
#include <cstring>
#include <cmath>
#include <nlohmann/json.hpp>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include "schema.hpp"
#include "sqlite.hpp"
#include "store_identity.hpp"
#include "store_rows.hpp"

namespace fogbench::storage {

// ---------------------------------------------------------------- names

std::string_view to_string(StoreErrc code) {
  switch (code) {
    case StoreErrc::open_failed: return "open_failed";
    case StoreErrc::not_fogbench: return "not_fogbench";
    case StoreErrc::schema_too_new: return "schema_too_new";
    case StoreErrc::schema_too_old: return "schema_too_old";
    case StoreErrc::migration_failed: return "migration_failed";
    case StoreErrc::not_found: return "not_found";
    case StoreErrc::invalid_argument: return "invalid_argument";
    case StoreErrc::constraint: return "constraint";
    case StoreErrc::read_only: return "read_only";
    case StoreErrc::disk_full: return "disk_full";
    case StoreErrc::io: return "io";
    case StoreErrc::busy: return "busy";
    case StoreErrc::corrupt: return "corrupt";
    case StoreErrc::sqlite: return "sqlite";
    case StoreErrc::pruned: return "pruned";
  }
  return "unknown";
}

namespace {

constexpr RunState kStates[] = {RunState::pending,   RunState::settling, RunState::running,
                                RunState::completed, RunState::aborted,  RunState::failed,
                                RunState::interrupted};
constexpr EventKind kKinds[] = {EventKind::state, EventKind::phase, EventKind::command,
                                EventKind::alarm, EventKind::fault, EventKind::note};

template <class Enum, std::size_t N>
std::optional<Enum> from_string(const Enum (&all)[N], std::string_view s) {
  for (Enum e : all)
    if (to_string(e) == s) return e;
  return std::nullopt;
}

}  // namespace

std::string_view to_string(RunState s) {
  switch (s) {
    case RunState::pending: return "pending";
    case RunState::settling: return "settling";
    case RunState::running: return "running";
    case RunState::completed: return "completed";
    case RunState::aborted: return "aborted";
    case RunState::failed: return "failed";
    case RunState::interrupted: return "interrupted";
  }
  return "unknown";
}
std::optional<RunState> run_state_from_string(std::string_view s) { return from_string(kStates, s); }
bool is_terminal(RunState s) {
  return s == RunState::completed || s == RunState::aborted || s == RunState::failed ||
         s == RunState::interrupted;
}

std::string_view to_string(Purpose p) { return p == Purpose::fit ? "fit" : "verify"; }
std::optional<Purpose> purpose_from_string(std::string_view s) {
  if (s == "fit") return Purpose::fit;
  if (s == "verify") return Purpose::verify;
  return std::nullopt;
}

std::string_view to_string(EventKind k) {
  switch (k) {
    case EventKind::state: return "state";
    case EventKind::phase: return "phase";
    case EventKind::command: return "command";
    case EventKind::alarm: return "alarm";
    case EventKind::fault: return "fault";
    case EventKind::note: return "note";
  }
  return "unknown";
}
std::optional<EventKind> event_kind_from_string(std::string_view s) {
  return from_string(kKinds, s);
}

// ---------------------------------------------------------------- open

Store::Store(std::unique_ptr<detail::Database> db) : db_(std::move(db)) {}
Store::Store(Store&&) noexcept = default;
Store& Store::operator=(Store&&) noexcept = default;
Store::~Store() = default;

int Store::current_schema_version() { return detail::current_version(); }
int Store::schema_version() const {
  assert(db_);
  return db_->version;
}
const std::filesystem::path& Store::path() const {
  assert(db_);
  return db_->path();
}

namespace {
// A new database file made with OpenOptions::file_mode before SQLite opens it (SQLite would make
// it 0644 less the umask). SQLite gives the -wal and -shm the database file's mode, with fchmod.
StoreResult<void> create_with_mode(const std::filesystem::path& path, unsigned mode) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC | O_NOFOLLOW, static_cast<::mode_t>(mode));
  if (fd < 0) {
    if (errno == EEXIST) return {};  // made meanwhile: it keeps its mode
    StoreError e;
    e.code = StoreErrc::open_failed;
    e.message = "cannot create database '" + path.string() + "': " + std::strerror(errno);
    return std::unexpected(std::move(e));
  }
  const int rc = ::fchmod(fd, static_cast<::mode_t>(mode));
  const int err = errno;
  ::close(fd);
  if (rc != 0) {
    StoreError e;
    e.code = StoreErrc::open_failed;
    e.message = "cannot set the mode of database '" + path.string() + "': " + std::strerror(err);
    return std::unexpected(std::move(e));
  }
  return {};
}

// Before a migration, the file as it is, next to it: `<store>.schema-<N>.bak` (VACUUM INTO: a
// consistent copy with the WAL's commits in it, written to a temporary name and renamed, so a
// copy cut short never stands as the backup; an older backup of the same version is replaced
// by this newer one). The way back to the fogbench that wrote version N (docs/storage.md,
// "Upgrade and downgrade"). A failure (no space, a read-only directory) refuses the migration.
StoreResult<std::filesystem::path> backup_before_migration(Database& db, const std::filesystem::path& path,
                                                          int from_version, int to_version) {
  const std::filesystem::path backup = path.string() + ".schema-" + std::to_string(from_version) + ".bak";
  const std::filesystem::path tmp = backup.string() + ".tmp-" + std::to_string(::getpid());
  const std::string what = "back up '" + path.string() + "' to '" + backup.string() + "' before migrating schema " +
                           std::to_string(from_version) + " -> " + std::to_string(to_version);
  auto refused = [&](std::string why) {
    std::error_code ignored;
    std::filesystem::remove(tmp, ignored);
    StoreError e;
    e.code = StoreErrc::migration_failed;
    e.message = "cannot " + what + ": " + why + "; the store was not migrated and is unchanged";
    return std::unexpected(std::move(e));
  };
  std::error_code ec;
  std::filesystem::remove(tmp, ec);  // a copy of an earlier attempt cut short
  std::string quoted;
  for (const char c : tmp.string()) quoted += c == '\'' ? std::string("''") : std::string(1, c);
  if (auto ok = db.exec("VACUUM INTO '" + quoted + "'", "VACUUM INTO"); !ok) return refused(ok.error().message);
  // The backup holds what the store holds: the store's mode, not the umask's.
  const auto mode = std::filesystem::status(path, ec).permissions();
  if (!ec) std::filesystem::permissions(tmp, mode, ec);
  if (ec) return refused("setting its mode: " + ec.message());
  std::filesystem::rename(tmp, backup, ec);
  if (ec) return refused(ec.message());
  return backup;
}

// The size limit's shares (OpenOptions::size_limit_bytes): the WAL index, then the WAL (a
// quarter of the limit, at most 4 MiB, SQLite's default checkpoint size), the rest the file.
constexpr std::int64_t kShmBytes = 32 * 1024;  // one WAL-index block: up to 4096 WAL frames
std::int64_t wal_budget(std::int64_t limit) { return std::min<std::int64_t>(limit / 4, 4 << 20); }
}  // namespace

StoreResult<Store> Store::open(const std::filesystem::path& path, const OpenOptions& options) {
  int flags = SQLITE_OPEN_NOMUTEX;  // one thread at a time: see the header
  const bool on_disk = path != ":memory:" && !path.string().starts_with("file:");
  if (!options.read_only && options.create && on_disk && !std::filesystem::exists(path))
    if (auto made = create_with_mode(path, options.file_mode); !made) return std::unexpected(made.error());
  if (options.read_only)
    flags |= SQLITE_OPEN_READONLY;
  else
    flags |= SQLITE_OPEN_READWRITE | (options.create ? SQLITE_OPEN_CREATE : 0);
  sqlite3* handle = nullptr;
  const int rc = sqlite3_open_v2(path.c_str(), &handle, flags, nullptr);
  if (rc != SQLITE_OK) {
    StoreError e;
    e.code = StoreErrc::open_failed;
    e.sqlite_code = rc;
    e.message = "cannot open database '" + path.string() +
                "': " + (handle ? sqlite3_errmsg(handle) : sqlite3_errstr(rc));
    sqlite3_close(handle);
    return std::unexpected(std::move(e));
  }
  sqlite3_extended_result_codes(handle, 1);
  sqlite3_busy_timeout(handle, options.busy_timeout_ms);
  auto db = std::make_unique<Database>(handle, path, options);
  db->busy_timeout_ms = options.busy_timeout_ms;

  // Look before writing anything: a foreign or newer file must stay exactly as it was.
  auto version = detail::inspect_schema(*db);
  if (!version) return fail(std::move(version));
  if (auto ok = db->exec("PRAGMA foreign_keys = ON", "enable foreign keys"); !ok)
    return fail(std::move(ok));

  // SQLite opens a file it may not write (its mode, a read-only filesystem) read-only without a
  // word, and writes then fail as they come (store_failure_test). A file that needs migrating
  // cannot be used at all that way: said at once, naming the file, before anything is written.
  if (!options.read_only && *version > 0 && *version < detail::current_version() &&
      sqlite3_db_readonly(db->handle(), "main") == 1)
    return std::unexpected(db->error(
        StoreErrc::read_only,
        "schema version " + std::to_string(*version) + " needs migrating to " +
            std::to_string(detail::current_version()) +
            ", but the file or its filesystem is read-only; nothing was changed (make it writable "
            "for the upgrade, or use the fogbench that wrote it)"));
  if (options.read_only) {
    if (*version < detail::current_version())
      return std::unexpected(db->error(
          StoreErrc::schema_too_old,
          "schema version " + std::to_string(*version) + " needs migrating to " +
              std::to_string(detail::current_version()) +
              ", which a read-only open cannot do; open it once read-write"));
    db->version = *version;
  } else {
    // WAL: readers (fogctl) never block the daemon's writes, and a commit appends to the log
    // instead of rewriting pages. The mode is persistent in the file.
    {
      auto stmt = db->statement("PRAGMA journal_mode = WAL");
      if (!stmt) return fail(std::move(stmt));
      Query q(*db, *stmt);
      auto got = row(*db, q, "set journal_mode=WAL");
      if (!got) return fail(std::move(got));
      const std::string mode = *got ? q.text(0) : std::string();
      if (mode != "wal" && mode != "memory")  // an in-memory database has no journal file
        return std::unexpected(db->error(StoreErrc::sqlite,
                                         "journal_mode=WAL refused (mode is '" + mode + "')"));
    }
    const char* sync =
        options.synchronous_full ? "PRAGMA synchronous = FULL" : "PRAGMA synchronous = NORMAL";
    if (auto ok = db->exec(sync, "set synchronous"); !ok) return fail(std::move(ok));
    if (options.backup_before_migration && on_disk && *version > 0 && *version < detail::current_version()) {
      auto backup = backup_before_migration(*db, path, *version, detail::current_version());
      if (!backup) return fail(std::move(backup));
    }
    auto migrated = detail::migrate(*db, *version);
    if (!migrated) return fail(std::move(migrated));
    db->version = *migrated;
  }

  if (options.size_limit_bytes) {
    const std::int64_t page = 4096;  // SQLite's default page size, fixed when the file is made
    auto stmt = db->statement("PRAGMA page_size");
    if (!stmt) return fail(std::move(stmt));
    std::int64_t page_size = page;
    {
      Query q(*db, *stmt);
      auto got = row(*db, q, "read page_size");
      if (!got) return fail(std::move(got));
      if (*got) page_size = q.int64(0);
    }
    // The files on disk count: the WAL and its index take their shares first (none in memory).
    const std::int64_t limit = *options.size_limit_bytes;
    const std::int64_t wal = on_disk ? wal_budget(limit) : 0;
    const std::int64_t pages = std::max<std::int64_t>(1, (limit - wal - (on_disk ? kShmBytes : 0)) / page_size);
    db->size_limit_bytes = limit;
    db->wal_budget_bytes = wal;
    if (on_disk && !options.read_only) {
      // SQLite checkpoints after a commit that leaves half the share in the log, and cuts the
      // log file back to the share after a checkpoint; keep_wal_within_limit does the rest.
      const std::int64_t frame = page_size + 24;  // a WAL frame: its header and the page
      const std::int64_t frames = std::max<std::int64_t>(1, (wal / 2 - 32) / frame);
      if (auto ok = db->exec("PRAGMA wal_autocheckpoint = " + std::to_string(frames), "set wal_autocheckpoint"); !ok)
        return fail(std::move(ok));
      if (auto ok = db->exec("PRAGMA journal_size_limit = " + std::to_string(wal), "set journal_size_limit"); !ok)
        return fail(std::move(ok));
      // A log left large by an earlier process without the limit, or a crash: into the file now.
      (void)db->checkpoint_truncate();
    }
    db->limit_pages = pages;
    db->reserve_pages = std::min<std::int64_t>(kReservePages, pages / 4);
    if (auto ok = db->exec("PRAGMA max_page_count = " + std::to_string(pages - db->reserve_pages),
                           "set size limit");
        !ok)
      return fail(std::move(ok));
  }
  return Store(std::move(db));
}

// ---------------------------------------------------------------- runs

int Store::busy_timeout_ms() const {
  assert(db_);
  return db_->busy_timeout_ms;
}

void Store::set_busy_timeout_ms(int ms) {
  assert(db_);
  db_->busy_timeout_ms = std::max(0, ms);
  sqlite3_busy_timeout(db_->handle(), db_->busy_timeout_ms);
}

StoreResult<std::int64_t> Store::create_run(const NewRun& r) {
  assert(db_);
  Database& db = *db_;
  const std::string_view config = json_or_empty_object(r.config_json);
  if (!is_json(config))
    return std::unexpected(
        db.error(StoreErrc::invalid_argument, "create run: config_json is not valid JSON"));
  if (!(std::isfinite(r.time_scale) && r.time_scale > 0))
    return std::unexpected(db.error(StoreErrc::invalid_argument,
                                    "create run: time_scale must be > 0, got " +
                                        format_number(r.time_scale)));

  const std::string what = "create run of profile '" + r.profile_name + "'";
  Transaction tx(db);
  if (auto ok = tx.begin(what); !ok) return fail(std::move(ok));
  auto stmt = db.statement(
      "INSERT INTO runs (created_at, profile_name, profile_text, purpose, state, config_json, "
      "time_scale) VALUES (?1, ?2, ?3, ?4, 'pending', ?5, ?6)");
  if (!stmt) return fail(std::move(stmt));
  {
    Query q(db, *stmt);
    q.bind(1, db.now_iso())
        .bind(2, r.profile_name)
        .bind(3, r.profile_text)
        .bind(4, to_string(r.purpose))
        .bind(5, config)
        .bind(6, r.time_scale);
    if (auto ok = run(db, q, what); !ok) return fail(std::move(ok));
  }
  const std::int64_t id = sqlite3_last_insert_rowid(db.handle());

  auto unit = db.statement("INSERT INTO run_units (run_id, unit_index, serial, lot, slot, axes) VALUES (?1, ?2, ?3, ?4, ?5, ?6)");
  if (!unit) return fail(std::move(unit));
  for (std::size_t i = 0; i < r.unit_serials.size(); ++i) {
    Query q(db, *unit);
    q.bind(1, id).bind(2, static_cast<int>(i)).bind(3, r.unit_serials[i]);
    q.bind(4, i < r.unit_lots.size() ? r.unit_lots[i] : std::nullopt);
    q.bind(5, i < r.unit_slots.size() && !r.unit_slots[i].empty() ? std::optional<std::string>(r.unit_slots[i]) : std::nullopt);
    q.bind(6, i < r.unit_axes.size() ? r.unit_axes[i] : 1);
    if (auto ok = run(db, q, what + ": unit " + std::to_string(i)); !ok)
      return fail(std::move(ok));
  }
  if (r.identity) {
    if (auto ok = insert_identity(db, id, *r.identity, what); !ok) return fail(std::move(ok));
  }
  const std::string detail = nlohmann::json{{"to", "pending"}, {"reason", "created"}}.dump();
  if (auto ok = insert_event(db, id, std::nullopt, EventKind::state, detail); !ok)
    return fail(std::move(ok));
  if (auto ok = tx.commit(what); !ok) return fail(std::move(ok));
  return id;
}

StoreResult<void> Store::set_run_state(std::int64_t run_id, RunState state,
                                       std::string_view reason, std::optional<double> t_s) {
  assert(db_);
  Database& db = *db_;
  return with_reserve(db, [&]() -> StoreResult<void> {
  const std::string what =
      "set " + run_label(run_id) + " to " + std::string(to_string(state));
  Transaction tx(db);
  if (auto ok = tx.begin(what); !ok) return fail(std::move(ok));

  std::string from;
  {
    auto stmt = db.statement("SELECT state FROM runs WHERE id = ?1");
    if (!stmt) return fail(std::move(stmt));
    Query q(db, *stmt);
    q.bind(1, run_id);
    auto found = row(db, q, what);
    if (!found) return fail(std::move(found));
    if (!*found) return std::unexpected(db.error(StoreErrc::not_found, what + ": no such run"));
    from = q.text(0);
  }
  const std::string now = db.now_iso();
  {
    // started_at: the first time the run leaves pending; ended_at: when it reaches a terminal
    // state (cleared should it be resumed).
    auto stmt = db.statement(
        "UPDATE runs SET state = ?2, state_reason = ?3, "
        "started_at = CASE WHEN ?4 AND started_at IS NULL THEN ?5 ELSE started_at END, "
        "ended_at = CASE WHEN ?6 THEN ?5 ELSE NULL END WHERE id = ?1");
    if (!stmt) return fail(std::move(stmt));
    Query q(db, *stmt);
    const bool starts = state == RunState::settling || state == RunState::running;
    q.bind(1, run_id)
        .bind(2, to_string(state))
        .bind(3, reason)
        .bind(4, starts ? 1 : 0)
        .bind(5, now)
        .bind(6, is_terminal(state) ? 1 : 0);
    if (auto ok = run(db, q, what); !ok) return fail(std::move(ok));
  }
  const std::string detail =
      nlohmann::json{{"from", from}, {"to", to_string(state)}, {"reason", reason}}.dump();
  if (auto ok = insert_event(db, run_id, t_s, EventKind::state, detail); !ok)
    return fail(std::move(ok));
  if (auto ok = tx.commit(what); !ok) return fail(std::move(ok));
  return {};
  });
}

StoreResult<std::int64_t> Store::add_event(std::int64_t run_id, EventKind kind,
                                           std::string_view detail_json,
                                           std::optional<double> t_s) {
  assert(db_);
  Database& db = *db_;
  const std::string_view detail = json_or_empty_object(detail_json);
  if (!is_json(detail))
    return std::unexpected(db.error(StoreErrc::invalid_argument,
                                    "add a " + std::string(to_string(kind)) + " event to " +
                                        run_label(run_id) + ": detail is not valid JSON"));
  if (auto ok = require_run(db, run_id); !ok) return fail(std::move(ok));
  return with_reserve(db, [&] { return insert_event(db, run_id, t_s, kind, detail); });
}

namespace {

StoreResult<std::vector<RunUnit>> load_units(Database& db, std::int64_t run_id) {
  auto stmt = db.statement(
      "SELECT unit_index, serial, lot, slot, axes FROM run_units WHERE run_id = ?1 ORDER BY unit_index");
  if (!stmt) return fail(std::move(stmt));
  Query q(db, *stmt);
  q.bind(1, run_id);
  std::vector<RunUnit> units;
  int rc;
  while ((rc = q.step()) == SQLITE_ROW)
    units.push_back(RunUnit{static_cast<int>(q.int64(0)), q.text(1), q.opt_text(2), q.opt_text(3), static_cast<int>(q.int64(4))});
  if (rc != SQLITE_DONE)
    return std::unexpected(db.error(rc, "read the units of " + run_label(run_id)));
  return units;
}

}  // namespace

StoreResult<std::vector<RunRecord>> Store::list_runs() { return list_runs(RunFilter{}); }

StoreResult<std::vector<RunRecord>> Store::list_runs(const RunFilter& f) {
  assert(db_);
  Database& db = *db_;
  if (f.limit < 0 || f.offset < 0)
    return std::unexpected(
        db.error(StoreErrc::invalid_argument, "list runs: limit and offset must be >= 0"));
  // One statement for every filter combination: a NULL parameter disables its condition.
  auto stmt = db.statement(
      "SELECT " FOGBENCH_RUN_COLUMNS
      " FROM runs WHERE (?1 IS NULL OR state = ?1) AND (?2 IS NULL OR purpose = ?2) "
      "AND (?3 IS NULL OR id IN (SELECT run_id FROM run_units WHERE serial = ?3)) "
      "AND (?4 IS NULL OR profile_name = ?4) ORDER BY id DESC LIMIT ?5 OFFSET ?6");
  if (!stmt) return fail(std::move(stmt));
  std::vector<RunRecord> runs;
  {
    Query q(db, *stmt);
    if (f.state) q.bind(1, to_string(*f.state));
    if (f.purpose) q.bind(2, to_string(*f.purpose));
    if (f.serial) q.bind(3, *f.serial);
    if (f.profile_name) q.bind(4, *f.profile_name);
    q.bind(5, f.limit).bind(6, f.offset);
    int rc;
    while ((rc = q.step()) == SQLITE_ROW) {
      auto r = read_run(db, q);
      if (!r) return fail(std::move(r));
      runs.push_back(std::move(*r));
    }
    if (rc != SQLITE_DONE) return std::unexpected(db.error(rc, "list runs"));
  }
  for (RunRecord& r : runs) {
    auto units = load_units(db, r.id);
    if (!units) return fail(std::move(units));
    r.units = std::move(*units);
  }
  return runs;
}

StoreResult<RunDetail> Store::get_run(std::int64_t run_id) {
  assert(db_);
  Database& db = *db_;
  RunDetail d;
  {
    auto stmt = db.statement("SELECT " FOGBENCH_RUN_COLUMNS " FROM runs WHERE id = ?1");
    if (!stmt) return fail(std::move(stmt));
    Query q(db, *stmt);
    q.bind(1, run_id);
    auto found = row(db, q, "read " + run_label(run_id));
    if (!found) return fail(std::move(found));
    if (!*found) return std::unexpected(db.error(StoreErrc::not_found, "no " + run_label(run_id)));
    auto r = read_run(db, q);
    if (!r) return fail(std::move(r));
    d.run = std::move(*r);
  }
  auto units = load_units(db, run_id);
  if (!units) return fail(std::move(units));
  d.run.units = std::move(*units);

  auto stmt = db.statement(
      "SELECT id, run_id, t_s, at, kind, detail FROM run_events WHERE run_id = ?1 ORDER BY id");
  if (!stmt) return fail(std::move(stmt));
  Query q(db, *stmt);
  q.bind(1, run_id);
  int rc;
  while ((rc = q.step()) == SQLITE_ROW) {
    RunEvent e;
    e.id = q.int64(0);
    e.run_id = q.int64(1);
    e.t_s = q.opt_real(2);
    e.at = q.text(3);
    e.kind = event_kind_from_string(q.text(4)).value_or(EventKind::note);
    e.detail_json = q.text(5);
    d.events.push_back(std::move(e));
  }
  if (rc != SQLITE_DONE)
    return std::unexpected(db.error(rc, "read the events of " + run_label(run_id)));
  return d;
}

StoreResult<std::vector<std::int64_t>> Store::mark_interrupted_runs(std::string_view reason) {
  assert(db_);
  Database& db = *db_;
  return with_reserve(db, [&]() -> StoreResult<std::vector<std::int64_t>> {
  const std::string what = "mark interrupted runs";
  Transaction tx(db);
  if (auto ok = tx.begin(what); !ok) return fail(std::move(ok));
  std::vector<std::pair<std::int64_t, std::string>> found;
  {
    auto stmt = db.statement(
        "SELECT id, state FROM runs WHERE state IN ('settling', 'running') ORDER BY id");
    if (!stmt) return fail(std::move(stmt));
    Query q(db, *stmt);
    int rc;
    while ((rc = q.step()) == SQLITE_ROW) found.emplace_back(q.int64(0), q.text(1));
    if (rc != SQLITE_DONE) return std::unexpected(db.error(rc, what));
  }
  const std::string now = db.now_iso();
  std::vector<std::int64_t> ids;
  for (const auto& [id, from] : found) {
    std::optional<double> last_t_s;
    {
      auto stmt = db.statement("SELECT MAX(t_s) FROM samples WHERE run_id = ?1");
      if (!stmt) return fail(std::move(stmt));
      Query q(db, *stmt);
      q.bind(1, id);
      auto got = row(db, q, what);
      if (!got) return fail(std::move(got));
      if (*got) last_t_s = q.opt_real(0);
    }
    {
      auto stmt = db.statement(
          "UPDATE runs SET state = 'interrupted', state_reason = ?2, ended_at = ?3 "
          "WHERE id = ?1");
      if (!stmt) return fail(std::move(stmt));
      Query q(db, *stmt);
      q.bind(1, id).bind(2, reason).bind(3, now);
      if (auto ok = run(db, q, what); !ok) return fail(std::move(ok));
    }
    const std::string detail =
        nlohmann::json{{"from", from}, {"to", "interrupted"}, {"reason", reason}}.dump();
    if (auto ok = insert_event(db, id, last_t_s, EventKind::state, detail); !ok)
      return fail(std::move(ok));
    ids.push_back(id);
  }
  if (auto ok = tx.commit(what); !ok) return fail(std::move(ok));
  return ids;
  });
}

// ---------------------------------------------------------------- maintenance

StoreResult<std::vector<std::string>> Store::integrity_check() {
  assert(db_);
  Database& db = *db_;
  std::vector<std::string> problems;
  {
    auto stmt = db.statement("PRAGMA integrity_check");
    if (!stmt) return fail(std::move(stmt));
    Query q(db, *stmt);
    int rc;
    while ((rc = q.step()) == SQLITE_ROW) {
      std::string line = q.text(0);
      if (line != "ok") problems.push_back(std::move(line));
    }
    if (rc != SQLITE_DONE) return std::unexpected(db.error(rc, "integrity check"));
  }
  {
    auto stmt = db.statement("PRAGMA foreign_key_check");
    if (!stmt) return fail(std::move(stmt));
    Query q(db, *stmt);
    int rc;
    while ((rc = q.step()) == SQLITE_ROW) {
      std::string line = "table " + q.text(0);
      if (!q.is_null(1)) line += " row " + std::to_string(q.int64(1));
      line += " refers to a missing row of " + q.text(2);
      problems.push_back(std::move(line));
    }
    if (rc != SQLITE_DONE) return std::unexpected(db.error(rc, "foreign key check"));
  }
  return problems;
}

}  // namespace fogbench::storage
