// The Store API: opening, and every read and write of runs, samples, events, models and
// verifications, over the cached statements of sqlite.hpp.
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

namespace fogbench::storage {

using detail::Database;
using detail::Query;
using detail::Transaction;

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

// ---------------------------------------------------------------- helpers

namespace {

// With OpenOptions::size_limit_bytes, the last pages of the limit (16 KiB at 4 KiB pages, at
// most a quarter of it) are kept for the audit trail. Samples fill the store up to the reserve;
// when they fail for a full store, the run's end (its state, a note, the reason) must still be
// written, so state changes and events that fail with disk_full are tried once more with the
// reserve opened. A real full disk has no such reserve: there the retry fails too.
constexpr std::int64_t kReservePages = 4;

template <class Write>
auto with_reserve(Database& db, Write&& write) -> decltype(write()) {
  auto r = write();
  if (r || r.error().code != StoreErrc::disk_full || db.reserve_pages == 0) return r;
  if (!db.exec("PRAGMA max_page_count = " + std::to_string(db.limit_pages), "open the size limit's reserve"))
    return r;
  r = write();
  // Never below the file's size: SQLite keeps max_page_count at the page count then, so
  // samples still find no room.
  (void)db.exec("PRAGMA max_page_count = " + std::to_string(db.limit_pages - db.reserve_pages),
                "close the size limit's reserve");
  return r;
}

}  // namespace

namespace {

template <class T>
std::unexpected<StoreError> fail(StoreResult<T>&& r) {
  return std::unexpected(std::move(r).error());
}

std::string run_label(std::int64_t run_id) { return "run " + std::to_string(run_id); }

bool is_json(std::string_view text) { return nlohmann::json::accept(text.begin(), text.end()); }

std::string_view json_or_empty_object(std::string_view text) { return text.empty() ? "{}" : text; }

std::string format_number(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

// Steps a statement that returns no rows.
StoreResult<void> run(Database& db, Query& q, std::string_view what) {
  if (int rc = q.step(); rc != SQLITE_DONE) return std::unexpected(db.error(rc, what));
  return {};
}

// Steps a statement that returns at most one row: true when it returned one.
StoreResult<bool> row(Database& db, Query& q, std::string_view what) {
  const int rc = q.step();
  if (rc == SQLITE_ROW) return true;
  if (rc == SQLITE_DONE) return false;
  return std::unexpected(db.error(rc, what));
}

#define FOGBENCH_RUN_COLUMNS                                                                  \
  "id, created_at, profile_name, profile_text, purpose, state, state_reason, config_json, " \
  "started_at, ended_at, time_scale"
#define FOGBENCH_MODEL_COLUMNS \
  "id, serial, version, run_id, parent_id, created_at, model_json, method, terms"
#define FOGBENCH_SAMPLE_COLUMNS                                                              \
  "unit_index, t_s, wall_time, setpoint_c, chamber_c, gyro_dph, frames, t1_c, t2_c, phase, " \
  "step, flags, since_power_on_s"

constexpr std::string_view kInsertSample =
    "INSERT INTO samples (run_id, " FOGBENCH_SAMPLE_COLUMNS
    ") VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?14)";
constexpr std::string_view kInsertEvent =
    "INSERT INTO run_events (run_id, t_s, at, kind, detail) VALUES (?1, ?2, ?3, ?4, ?5)";
constexpr std::string_view kRunExists = "SELECT 1 FROM runs WHERE id = ?1";

StoreResult<RunRecord> read_run(Database& db, const Query& q) {
  RunRecord r;
  r.id = q.int64(0);
  r.created_at = q.text(1);
  r.profile_name = q.text(2);
  r.profile_text = q.text(3);
  const auto purpose = purpose_from_string(q.text(4));
  const auto state = run_state_from_string(q.text(5));
  // The CHECK constraints make these impossible unless the file was edited by hand.
  if (!purpose || !state)
    return std::unexpected(db.error(StoreErrc::corrupt, run_label(r.id) + " has purpose '" +
                                                            q.text(4) + "' and state '" +
                                                            q.text(5) + "'"));
  r.purpose = *purpose;
  r.state = *state;
  r.state_reason = q.text(6);
  r.config_json = q.text(7);
  r.started_at = q.opt_text(8);
  r.ended_at = q.opt_text(9);
  r.time_scale = q.real(10);
  return r;
}

ModelRecord read_model(const Query& q) {
  ModelRecord m;
  m.id = q.int64(0);
  m.serial = q.text(1);
  m.version = static_cast<int>(q.int64(2));
  m.run_id = q.opt_int64(3);
  m.parent_id = q.opt_int64(4);
  m.created_at = q.text(5);
  m.model_json = q.text(6);
  m.method = q.text(7);
  m.terms = q.text(8);
  return m;
}

SampleRow read_sample(const Query& q) {
  SampleRow s;
  s.unit_index = static_cast<int>(q.int64(0));
  s.t_s = q.real(1);
  s.wall_time = q.real(2);
  s.setpoint_c = q.real(3);
  s.chamber_c = q.real(4);
  s.gyro_dph = q.real(5);
  s.frames = q.opt_int64(6);
  s.t1_c = q.real(7);
  s.t2_c = q.real(8);
  s.phase = q.is_null(9) ? model::Phase::unknown : static_cast<model::Phase>(q.int64(9));
  if (!q.is_null(10)) s.step = static_cast<int>(q.int64(10));
  s.flags = static_cast<std::uint8_t>(q.int64(11));
  s.since_power_on_s = q.real(12);
  return s;
}

StoreResult<bool> run_exists(Database& db, std::int64_t run_id) {
  auto stmt = db.statement(kRunExists);
  if (!stmt) return fail(std::move(stmt));
  Query q(db, *stmt);
  q.bind(1, run_id);
  return row(db, q, "look up " + run_label(run_id));
}

StoreResult<void> require_run(Database& db, std::int64_t run_id) {
  auto found = run_exists(db, run_id);
  if (!found) return fail(std::move(found));
  if (!*found) return std::unexpected(db.error(StoreErrc::not_found, "no " + run_label(run_id)));
  return {};
}

StoreResult<std::optional<std::string>> unit_serial(Database& db, std::int64_t run_id,
                                                    int unit_index) {
  auto stmt = db.statement("SELECT serial FROM run_units WHERE run_id = ?1 AND unit_index = ?2");
  if (!stmt) return fail(std::move(stmt));
  Query q(db, *stmt);
  q.bind(1, run_id).bind(2, unit_index);
  auto found = row(db, q, "look up unit " + std::to_string(unit_index) + " of " +
                              run_label(run_id));
  if (!found) return fail(std::move(found));
  if (!*found) return std::optional<std::string>();
  return std::optional<std::string>(q.text(0));
}

// not_found naming the run or the unit that is missing.
StoreResult<std::string> require_unit(Database& db, std::int64_t run_id, int unit_index) {
  auto serial = unit_serial(db, run_id, unit_index);
  if (!serial) return fail(std::move(serial));
  if (*serial) return **serial;
  if (auto ok = require_run(db, run_id); !ok) return fail(std::move(ok));
  return std::unexpected(db.error(StoreErrc::not_found, run_label(run_id) + " has no unit " +
                                                            std::to_string(unit_index)));
}

StoreResult<std::int64_t> insert_event(Database& db, std::int64_t run_id,
                                       std::optional<double> t_s, EventKind kind,
                                       std::string_view detail) {
  auto stmt = db.statement(kInsertEvent);
  if (!stmt) return fail(std::move(stmt));
  Query q(db, *stmt);
  q.bind(1, run_id).bind(2, t_s).bind(3, db.now_iso()).bind(4, to_string(kind)).bind(5, detail);
  if (auto ok = run(db, q, "add a " + std::string(to_string(kind)) + " event to " +
                               run_label(run_id));
      !ok)
    return fail(std::move(ok));
  return sqlite3_last_insert_rowid(db.handle());
}

// Binds one sample to the insert statement (parameters 2..14; 1 is the run id).
void bind_sample(Query& q, const SampleRow& s) {
  q.bind(2, s.unit_index)
      .bind(3, s.t_s)
      .bind(4, s.wall_time)
      .bind(5, s.setpoint_c)
      .bind(6, s.chamber_c)
      .bind(7, s.gyro_dph)
      .bind(8, s.frames)
      .bind(9, s.t1_c)
      .bind(10, s.t2_c)
      .bind(11, static_cast<int>(s.phase))
      .bind(12, s.step)
      .bind(13, static_cast<int>(s.flags))
      .bind(14, s.since_power_on_s);
}

// The error of a failed sample insert, in the caller's terms when it is a constraint.
StoreError sample_error(Database& db, int rc, std::int64_t run_id, int unit_index, double t_s,
                        std::string_view what) {
  StoreError e = db.error(rc, what);
  if (rc == SQLITE_CONSTRAINT_PRIMARYKEY)
    e.message = std::string(what) + " in '" + db.path().string() + "': unit " +
                std::to_string(unit_index) + " of " + run_label(run_id) +
                " already has a sample at t_s " + format_number(t_s);
  else if (rc == SQLITE_CONSTRAINT_FOREIGNKEY)
    e.message = std::string(what) + " in '" + db.path().string() + "': " + run_label(run_id) +
                " has no unit " + std::to_string(unit_index) + " (or does not exist)";
  return e;
}

}  // namespace

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

  auto unit = db.statement("INSERT INTO run_units (run_id, unit_index, serial) VALUES (?1, ?2, ?3)");
  if (!unit) return fail(std::move(unit));
  for (std::size_t i = 0; i < r.unit_serials.size(); ++i) {
    Query q(db, *unit);
    q.bind(1, id).bind(2, static_cast<int>(i)).bind(3, r.unit_serials[i]);
    if (auto ok = run(db, q, what + ": unit " + std::to_string(i)); !ok)
      return fail(std::move(ok));
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
      "SELECT unit_index, serial FROM run_units WHERE run_id = ?1 ORDER BY unit_index");
  if (!stmt) return fail(std::move(stmt));
  Query q(db, *stmt);
  q.bind(1, run_id);
  std::vector<RunUnit> units;
  int rc;
  while ((rc = q.step()) == SQLITE_ROW)
    units.push_back(RunUnit{static_cast<int>(q.int64(0)), q.text(1)});
  if (rc != SQLITE_DONE)
    return std::unexpected(db.error(rc, "read the units of " + run_label(run_id)));
  return units;
}

}  // namespace

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

// ---------------------------------------------------------------- samples

StoreResult<void> Store::append_samples(std::int64_t run_id, std::span<const SampleRow> rows) {
  assert(db_);
  Database& db = *db_;
  if (rows.empty()) return {};
  const std::string what =
      "append " + std::to_string(rows.size()) + " samples to " + run_label(run_id);
  for (std::size_t i = 0; i < rows.size(); ++i)
    if (!std::isfinite(rows[i].t_s))
      return std::unexpected(db.error(StoreErrc::invalid_argument,
                                      what + ": row " + std::to_string(i) +
                                          " has a non-finite t_s"));

  Transaction tx(db);
  if (auto ok = tx.begin(what); !ok) return fail(std::move(ok));
  auto stmt = db.statement(kInsertSample);
  if (!stmt) return fail(std::move(stmt));
  {
    Query q(db, *stmt);
    q.bind(1, run_id);
    for (const SampleRow& s : rows) {
      bind_sample(q, s);
      if (int rc = q.step(); rc != SQLITE_DONE)
        return std::unexpected(sample_error(db, rc, run_id, s.unit_index, s.t_s, what));
      q.reset();
    }
  }
  if (auto ok = tx.commit(what); !ok) return fail(std::move(ok));
  return {};
}

StoreResult<std::int64_t> Store::count_samples(std::int64_t run_id,
                                               std::optional<int> unit_index) {
  assert(db_);
  Database& db = *db_;
  if (auto ok = require_run(db, run_id); !ok) return fail(std::move(ok));
  auto stmt = db.statement(
      "SELECT count(*) FROM samples WHERE run_id = ?1 AND (?2 IS NULL OR unit_index = ?2)");
  if (!stmt) return fail(std::move(stmt));
  Query q(db, *stmt);
  q.bind(1, run_id).bind(2, unit_index);
  auto got = row(db, q, "count the samples of " + run_label(run_id));
  if (!got) return fail(std::move(got));
  return q.int64(0);
}

StoreResult<std::vector<SampleRow>> Store::get_samples(std::int64_t run_id, int unit_index,
                                                       std::int64_t offset,
                                                       std::int64_t limit) {
  assert(db_);
  Database& db = *db_;
  const std::string what = "read samples of unit " + std::to_string(unit_index) + " of " +
                           run_label(run_id);
  if (offset < 0 || limit < 0)
    return std::unexpected(
        db.error(StoreErrc::invalid_argument, what + ": offset and limit must be >= 0"));
  if (auto ok = require_unit(db, run_id, unit_index); !ok) return fail(std::move(ok));
  auto stmt = db.statement("SELECT " FOGBENCH_SAMPLE_COLUMNS
                           " FROM samples WHERE run_id = ?1 AND unit_index = ?2 "
                           "ORDER BY t_s LIMIT ?3 OFFSET ?4");
  if (!stmt) return fail(std::move(stmt));
  Query q(db, *stmt);
  q.bind(1, run_id).bind(2, unit_index).bind(3, limit).bind(4, offset);
  std::vector<SampleRow> out;
  out.reserve(static_cast<std::size_t>(std::min<std::int64_t>(limit, 100000)));
  int rc;
  while ((rc = q.step()) == SQLITE_ROW) out.push_back(read_sample(q));
  if (rc != SQLITE_DONE) return std::unexpected(db.error(rc, what));
  return out;
}

// ---------------------------------------------------------------- RunData

StoreResult<model::RunData> Store::export_run(std::int64_t run_id, int unit_index,
                                              const ExportOptions& options) {
  assert(db_);
  Database& db = *db_;
  const std::string label = "unit " + std::to_string(unit_index) + " of " + run_label(run_id);
  auto serial = require_unit(db, run_id, unit_index);
  if (!serial) return fail(std::move(serial));
  auto count = count_samples(run_id, unit_index);
  if (!count) return fail(std::move(count));

  model::RunData d;
  d.name = run_label(run_id) + " unit " + std::to_string(unit_index) + " (" + *serial + ")";
  const auto n = static_cast<std::size_t>(*count);
  for (auto* v : {&d.time_s, &d.gyro_dph, &d.t1_c, &d.t2_c, &d.setpoint_c, &d.chamber_c})
    v->reserve(n);
  d.phase.reserve(n);
  d.step.reserve(n);
  d.flags.reserve(n);
  bool has_setpoint = false, has_chamber = false, has_phase = false, has_step = false,
       has_flags = false, has_power_on = false;
  std::size_t settle_skipped = 0;
  bool in_leading_settle = !options.include_settle;

  auto stmt = db.statement(
      "SELECT t_s, gyro_dph, t1_c, t2_c, setpoint_c, chamber_c, phase, step, flags, since_power_on_s "
      "FROM samples WHERE run_id = ?1 AND unit_index = ?2 ORDER BY t_s");
  if (!stmt) return fail(std::move(stmt));
  Query q(db, *stmt);
  q.bind(1, run_id).bind(2, unit_index);
  int rc;
  while ((rc = q.step()) == SQLITE_ROW) {
    const bool phase_null = q.is_null(6);
    const auto phase = phase_null ? model::Phase::unknown : static_cast<model::Phase>(q.int64(6));
    if (in_leading_settle) {
      if (phase == model::Phase::settle) {
        ++settle_skipped;
        continue;
      }
      in_leading_settle = false;
    }
    d.time_s.push_back(q.real(0));
    d.gyro_dph.push_back(q.real(1));
    d.t1_c.push_back(q.real(2));
    d.t2_c.push_back(q.real(3));
    has_setpoint |= !q.is_null(4);
    d.setpoint_c.push_back(q.real(4));
    has_chamber |= !q.is_null(5);
    d.chamber_c.push_back(q.real(5));
    has_phase |= !phase_null;
    d.phase.push_back(phase);
    has_step |= !q.is_null(7);
    d.step.push_back(q.is_null(7) ? -1 : static_cast<int>(q.int64(7)));
    has_flags |= !q.is_null(8);
    d.flags.push_back(static_cast<std::uint8_t>(q.int64(8)));
    has_power_on |= !q.is_null(9);
    d.since_power_on_s.push_back(q.real(9));
  }
  if (rc != SQLITE_DONE) return std::unexpected(db.error(rc, "export " + label));
  if (d.size() == 0) {
    std::string why = label + " has no samples";
    if (settle_skipped)
      why += " after the settle phase (" + std::to_string(settle_skipped) +
             " settle samples; include_settle exports them)";
    return std::unexpected(db.error(StoreErrc::not_found, "export: " + why));
  }
  // A column no exported sample has is "not recorded", as in a CSV without it.
  auto drop = [](bool keep, auto& column) {
    if (!keep) {
      column.clear();
      column.shrink_to_fit();
    }
  };
  drop(has_setpoint, d.setpoint_c);
  drop(has_chamber, d.chamber_c);
  drop(has_phase, d.phase);
  drop(has_step, d.step);
  drop(has_flags, d.flags);
  drop(has_power_on, d.since_power_on_s);
  return d;
}

StoreResult<std::int64_t> Store::import_run(const model::RunData& data,
                                            const ImportOptions& options) {
  assert(db_);
  Database& db = *db_;
  const std::string what = "import '" + data.name + "'";
  auto invalid = [&](const std::string& why) {
    return std::unexpected(db.error(StoreErrc::invalid_argument, what + ": " + why));
  };
  const std::size_t n = data.size();
  if (options.serial.empty()) return invalid("no unit serial given");
  if (n == 0) return invalid("no samples");
  const std::pair<std::string_view, std::size_t> sizes[] = {
      {"gyro_dph", data.gyro_dph.size()},     {"t1_c", data.t1_c.size()},
      {"t2_c", data.t2_c.size()},             {"setpoint_c", data.setpoint_c.size()},
      {"chamber_c", data.chamber_c.size()},   {"phase", data.phase.size()},
      {"step", data.step.size()},             {"flags", data.flags.size()},
      {"since_power_on_s", data.since_power_on_s.size()}};
  for (std::size_t c = 0; c < std::size(sizes); ++c) {
    const bool required = c < 3;
    const auto [name, size] = sizes[c];
    if (size != n && (required || size != 0))
      return invalid(std::string(name) + " has " + std::to_string(size) +
                     " values but time_s has " + std::to_string(n));
  }
  for (std::size_t i = 0; i < n; ++i)
    if (!std::isfinite(data.time_s[i]))
      return invalid("time_s[" + std::to_string(i) + "] is not finite");
  const std::string_view config = json_or_empty_object(options.config_json);
  if (!is_json(config)) return invalid("config_json is not valid JSON");

  Transaction tx(db);
  if (auto ok = tx.begin(what); !ok) return fail(std::move(ok));
  {
    auto stmt = db.statement(
        "INSERT INTO runs (created_at, profile_name, purpose, state, state_reason, config_json) "
        "VALUES (?1, ?2, ?3, 'completed', ?4, ?5)");
    if (!stmt) return fail(std::move(stmt));
    Query q(db, *stmt);
    const std::string reason = "imported from " + data.name;
    q.bind(1, db.now_iso())
        .bind(2, options.profile_name)
        .bind(3, to_string(options.purpose))
        .bind(4, reason)
        .bind(5, config);
    if (auto ok = run(db, q, what); !ok) return fail(std::move(ok));
  }
  const std::int64_t id = sqlite3_last_insert_rowid(db.handle());
  {
    auto stmt =
        db.statement("INSERT INTO run_units (run_id, unit_index, serial) VALUES (?1, ?2, ?3)");
    if (!stmt) return fail(std::move(stmt));
    Query q(db, *stmt);
    q.bind(1, id).bind(2, 0).bind(3, options.serial);
    if (auto ok = run(db, q, what); !ok) return fail(std::move(ok));
  }
  {
    auto stmt = db.statement(kInsertSample);
    if (!stmt) return fail(std::move(stmt));
    Query q(db, *stmt);
    // Columns the data lacks stay NULL, so export_run gives back the same columns.
    q.bind(1, id).bind(2, 0).bind_null(4).bind_null(8);
    for (std::size_t i = 0; i < n; ++i) {
      q.bind(3, data.time_s[i]).bind(7, data.gyro_dph[i]).bind(9, data.t1_c[i]).bind(10, data.t2_c[i]);
      if (data.has_setpoint()) q.bind(5, data.setpoint_c[i]);
      if (data.has_chamber()) q.bind(6, data.chamber_c[i]);
      if (data.has_phase()) q.bind(11, static_cast<int>(data.phase[i]));
      if (data.has_step()) q.bind(12, data.step[i]);
      if (data.has_flags()) q.bind(13, static_cast<int>(data.flags[i]));
      if (data.has_power_on()) q.bind(14, data.since_power_on_s[i]);
      if (int rc = q.step(); rc != SQLITE_DONE)
        return std::unexpected(sample_error(db, rc, id, 0, data.time_s[i], what));
      q.reset();
    }
  }
  const std::string detail =
      nlohmann::json{{"imported_from", data.name}, {"samples", n}, {"serial", options.serial}}
          .dump();
  if (auto ok = insert_event(db, id, std::nullopt, EventKind::note, detail); !ok)
    return fail(std::move(ok));
  if (auto ok = tx.commit(what); !ok) return fail(std::move(ok));
  return id;
}

// ---------------------------------------------------------------- models

StoreResult<ModelRef> Store::put_model(const NewModel& m) {
  assert(db_);
  Database& db = *db_;
  const std::string what = "store a model for serial '" + m.serial + "'";
  if (m.serial.empty())
    return std::unexpected(db.error(StoreErrc::invalid_argument, what + ": empty serial"));
  if (!is_json(m.model_json))
    return std::unexpected(
        db.error(StoreErrc::invalid_argument, what + ": model_json is not valid JSON"));

  // IMMEDIATE: the next version number is read and used under the write lock, so two writers
  // cannot both take version n.
  Transaction tx(db);
  if (auto ok = tx.begin(what); !ok) return fail(std::move(ok));
  if (m.run_id) {
    if (auto ok = require_run(db, *m.run_id); !ok) return fail(std::move(ok));
  }
  if (m.parent_id) {
    auto parent = get_model(*m.parent_id);
    if (!parent) return fail(std::move(parent));
  }
  int version = 1;
  {
    auto stmt = db.statement("SELECT COALESCE(MAX(version), 0) + 1 FROM models WHERE serial = ?1");
    if (!stmt) return fail(std::move(stmt));
    Query q(db, *stmt);
    q.bind(1, m.serial);
    auto got = row(db, q, what);
    if (!got) return fail(std::move(got));
    version = static_cast<int>(q.int64(0));
  }
  {
    auto stmt = db.statement(
        "INSERT INTO models (serial, version, run_id, parent_id, created_at, model_json, method, "
        "terms) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8)");
    if (!stmt) return fail(std::move(stmt));
    Query q(db, *stmt);
    q.bind(1, m.serial)
        .bind(2, version)
        .bind(3, m.run_id)
        .bind(4, m.parent_id)
        .bind(5, db.now_iso())
        .bind(6, m.model_json)
        .bind(7, m.method)
        .bind(8, m.terms);
    if (auto ok = run(db, q, what); !ok) return fail(std::move(ok));
  }
  const std::int64_t id = sqlite3_last_insert_rowid(db.handle());
  if (auto ok = tx.commit(what); !ok) return fail(std::move(ok));
  return ModelRef{id, version};
}

StoreResult<ModelRecord> Store::get_model(std::int64_t model_id) {
  assert(db_);
  Database& db = *db_;
  auto stmt = db.statement("SELECT " FOGBENCH_MODEL_COLUMNS " FROM models WHERE id = ?1");
  if (!stmt) return fail(std::move(stmt));
  Query q(db, *stmt);
  q.bind(1, model_id);
  const std::string what = "model " + std::to_string(model_id);
  auto found = row(db, q, "read " + what);
  if (!found) return fail(std::move(found));
  if (!*found) return std::unexpected(db.error(StoreErrc::not_found, "no " + what));
  return read_model(q);
}

StoreResult<std::optional<ModelRecord>> Store::current_model(std::string_view serial) {
  assert(db_);
  Database& db = *db_;
  auto stmt = db.statement("SELECT " FOGBENCH_MODEL_COLUMNS
                           " FROM models WHERE serial = ?1 ORDER BY version DESC LIMIT 1");
  if (!stmt) return fail(std::move(stmt));
  Query q(db, *stmt);
  q.bind(1, serial);
  auto found = row(db, q, "read the current model of '" + std::string(serial) + "'");
  if (!found) return fail(std::move(found));
  if (!*found) return std::optional<ModelRecord>();
  return std::optional<ModelRecord>(read_model(q));
}

StoreResult<std::vector<ModelRecord>> Store::list_models(std::string_view serial) {
  assert(db_);
  Database& db = *db_;
  auto stmt = db.statement("SELECT " FOGBENCH_MODEL_COLUMNS
                           " FROM models WHERE serial = ?1 ORDER BY version");
  if (!stmt) return fail(std::move(stmt));
  Query q(db, *stmt);
  q.bind(1, serial);
  std::vector<ModelRecord> out;
  int rc;
  while ((rc = q.step()) == SQLITE_ROW) out.push_back(read_model(q));
  if (rc != SQLITE_DONE)
    return std::unexpected(db.error(rc, "list the models of '" + std::string(serial) + "'"));
  return out;
}

StoreResult<std::vector<ModelRecord>> Store::model_lineage(std::int64_t model_id) {
  assert(db_);
  Database& db = *db_;
  // A parent is stored before its child, so the chain cannot loop; the depth bound only
  // protects against a file edited by hand.
  auto stmt = db.statement(
      "WITH RECURSIVE chain(id, depth) AS ("
      "  SELECT ?1, 0"
      "  UNION ALL SELECT m.parent_id, c.depth + 1 FROM models m JOIN chain c ON m.id = c.id"
      "  WHERE m.parent_id IS NOT NULL AND c.depth < 100000) "
      "SELECT m.id, m.serial, m.version, m.run_id, m.parent_id, m.created_at, m.model_json, "
      "m.method, m.terms FROM chain c JOIN models m ON m.id = c.id ORDER BY c.depth");
  if (!stmt) return fail(std::move(stmt));
  Query q(db, *stmt);
  q.bind(1, model_id);
  std::vector<ModelRecord> out;
  int rc;
  while ((rc = q.step()) == SQLITE_ROW) out.push_back(read_model(q));
  const std::string what = "model " + std::to_string(model_id);
  if (rc != SQLITE_DONE) return std::unexpected(db.error(rc, "read the lineage of " + what));
  if (out.empty()) return std::unexpected(db.error(StoreErrc::not_found, "no " + what));
  return out;
}

StoreResult<std::int64_t> Store::put_verification(const NewVerification& v) {
  assert(db_);
  Database& db = *db_;
  const std::string what = "store a verification of model " + std::to_string(v.model_id) +
                           " on unit " + std::to_string(v.unit_index) + " of " +
                           run_label(v.run_id);
  if (!is_json(v.result_json))
    return std::unexpected(
        db.error(StoreErrc::invalid_argument, what + ": result_json is not valid JSON"));
  Transaction tx(db);
  if (auto ok = tx.begin(what); !ok) return fail(std::move(ok));
  if (auto ok = require_unit(db, v.run_id, v.unit_index); !ok) return fail(std::move(ok));
  if (auto ok = get_model(v.model_id); !ok) return fail(std::move(ok));
  auto stmt = db.statement(
      "INSERT INTO verifications (run_id, unit_index, model_id, created_at, result_json, pass) "
      "VALUES (?1, ?2, ?3, ?4, ?5, ?6)");
  if (!stmt) return fail(std::move(stmt));
  {
    Query q(db, *stmt);
    q.bind(1, v.run_id)
        .bind(2, v.unit_index)
        .bind(3, v.model_id)
        .bind(4, db.now_iso())
        .bind(5, v.result_json)
        .bind(6, v.pass ? 1 : 0);
    if (auto ok = run(db, q, what); !ok) return fail(std::move(ok));
  }
  const std::int64_t id = sqlite3_last_insert_rowid(db.handle());
  if (auto ok = tx.commit(what); !ok) return fail(std::move(ok));
  return id;
}

StoreResult<std::vector<VerificationRecord>> Store::list_verifications(std::int64_t run_id) {
  assert(db_);
  Database& db = *db_;
  if (auto ok = require_run(db, run_id); !ok) return fail(std::move(ok));
  auto stmt = db.statement(
      "SELECT id, run_id, unit_index, model_id, created_at, result_json, pass "
      "FROM verifications WHERE run_id = ?1 ORDER BY id");
  if (!stmt) return fail(std::move(stmt));
  Query q(db, *stmt);
  q.bind(1, run_id);
  std::vector<VerificationRecord> out;
  int rc;
  while ((rc = q.step()) == SQLITE_ROW) {
    VerificationRecord v;
    v.id = q.int64(0);
    v.run_id = q.int64(1);
    v.unit_index = static_cast<int>(q.int64(2));
    v.model_id = q.int64(3);
    v.created_at = q.text(4);
    v.result_json = q.text(5);
    v.pass = q.int64(6) != 0;
    out.push_back(std::move(v));
  }
  if (rc != SQLITE_DONE)
    return std::unexpected(db.error(rc, "list the verifications of " + run_label(run_id)));
  return out;
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
