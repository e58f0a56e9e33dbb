// The Store's row helpers (an internal header of storage/src/): statements run and read with
// errors that say what was being done, the reads of a run, model and sample row, and the checks
// every write makes (the run exists, the unit is the run's). Used by store.cpp (runs),
// store_samples.cpp (samples, RunData) and store_models.cpp (models, verifications).
#pragma once

#include <algorithm>
#include <cassert>
#include <cerrno>
#include <cmath>
#include <cstring>

#include <nlohmann/json.hpp>

#include "fogbench/storage/errors.hpp"
#include "fogbench/storage/models.hpp"
#include "fogbench/storage/runs.hpp"
#include "fogbench/storage/samples.hpp"
#include "schema.hpp"
#include "format_number.hpp"
#include "sqlite.hpp"

namespace fogbench::storage {

using detail::Database;
using detail::Query;
using detail::Transaction;

// ---------------------------------------------------------------- helpers

namespace detail {

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

}  // namespace detail

namespace detail {

template <class T>
std::unexpected<StoreError> fail(StoreResult<T>&& r) {
  return std::unexpected(std::move(r).error());
}

inline std::string run_label(std::int64_t run_id) { return "run " + std::to_string(run_id); }

inline bool is_json(std::string_view text) { return nlohmann::json::accept(text.begin(), text.end()); }

inline std::string_view json_or_empty_object(std::string_view text) { return text.empty() ? "{}" : text; }

using detail::format_number;

// Steps a statement that returns no rows.
inline StoreResult<void> run(Database& db, Query& q, std::string_view what) {
  if (int rc = q.step(); rc != SQLITE_DONE) return std::unexpected(db.error(rc, what));
  return {};
}

// Steps a statement that returns at most one row: true when it returned one.
inline StoreResult<bool> row(Database& db, Query& q, std::string_view what) {
  const int rc = q.step();
  if (rc == SQLITE_ROW) return true;
  if (rc == SQLITE_DONE) return false;
  return std::unexpected(db.error(rc, what));
}

#define FOGBENCH_RUN_COLUMNS                                                                  \
  "id, created_at, profile_name, profile_text, purpose, state, state_reason, config_json, " \
  "started_at, ended_at, time_scale, pruned_at, pruned_samples"
#define FOGBENCH_MODEL_COLUMNS \
  "id, serial, version, run_id, parent_id, created_at, model_json, method, terms, axis"
#define FOGBENCH_SAMPLE_COLUMNS                                                              \
  "unit_index, t_s, wall_time, setpoint_c, chamber_c, gyro_dph, frames, t1_c, t2_c, phase, " \
  "step, flags, since_power_on_s, compensated_dph, rate_in_dps, gyro_y_dph, gyro_z_dph, "  \
  "t1_y_c, t2_y_c, t1_z_c, t2_z_c"

constexpr std::string_view kInsertSample =
    "INSERT INTO samples (run_id, " FOGBENCH_SAMPLE_COLUMNS
    ") VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?14, ?15, ?16, ?17, ?18, ?19, ?20, ?21, ?22)";
constexpr std::string_view kInsertEvent =
    "INSERT INTO run_events (run_id, t_s, at, kind, detail) VALUES (?1, ?2, ?3, ?4, ?5)";
constexpr std::string_view kRunExists = "SELECT 1 FROM runs WHERE id = ?1";

inline StoreResult<RunRecord> read_run(Database& db, const Query& q) {
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
  r.pruned_at = q.opt_text(11);
  r.pruned_samples = q.int64(12);
  return r;
}

inline ModelRecord read_model(const Query& q) {
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
  m.axis = q.opt_text(9).value_or("");
  return m;
}

inline SampleRow read_sample(const Query& q) {
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
  s.compensated_dph = q.real(13);
  s.rate_in_dps = q.real(14);
  s.gyro_y_dph = q.real(15);
  s.gyro_z_dph = q.real(16);
  s.t1_y_c = q.real(17);
  s.t2_y_c = q.real(18);
  s.t1_z_c = q.real(19);
  s.t2_z_c = q.real(20);
  return s;
}

inline StoreResult<bool> run_exists(Database& db, std::int64_t run_id) {
  auto stmt = db.statement(kRunExists);
  if (!stmt) return fail(std::move(stmt));
  Query q(db, *stmt);
  q.bind(1, run_id);
  return row(db, q, "look up " + run_label(run_id));
}

inline StoreResult<void> require_run(Database& db, std::int64_t run_id) {
  auto found = run_exists(db, run_id);
  if (!found) return fail(std::move(found));
  if (!*found) return std::unexpected(db.error(StoreErrc::not_found, "no " + run_label(run_id)));
  return {};
}

inline StoreResult<std::optional<std::string>> unit_serial(Database& db, std::int64_t run_id,
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
inline StoreResult<std::string> require_unit(Database& db, std::int64_t run_id, int unit_index) {
  auto serial = unit_serial(db, run_id, unit_index);
  if (!serial) return fail(std::move(serial));
  if (*serial) return **serial;
  if (auto ok = require_run(db, run_id); !ok) return fail(std::move(ok));
  return std::unexpected(db.error(StoreErrc::not_found, run_label(run_id) + " has no unit " +
                                                            std::to_string(unit_index)));
}

// pruned when Store::prune deleted the run's samples: says when, how many, and where they are.
inline StoreResult<void> require_samples_kept(Database& db, std::int64_t run_id) {
  auto stmt = db.statement("SELECT pruned_at, pruned_samples FROM runs WHERE id = ?1 AND pruned_at IS NOT NULL");
  if (!stmt) return fail(std::move(stmt));
  Query q(db, *stmt);
  q.bind(1, run_id);
  auto found = row(db, q, "look up " + run_label(run_id));
  if (!found) return fail(std::move(found));
  if (!*found) return {};
  return std::unexpected(db.error(
      StoreErrc::pruned, "the samples of " + run_label(run_id) + " were pruned at " + q.text(0) + " (" +
                             std::to_string(q.int64(1)) +
                             " samples deleted by `fogctl store prune`; the plant store keeps the runs it received)"));
}

inline StoreResult<std::int64_t> insert_event(Database& db, std::int64_t run_id,
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

// Binds one sample to the insert statement (parameters 2..22; 1 is the run id).
inline void bind_sample(Query& q, const SampleRow& s) {
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
      .bind(14, s.since_power_on_s)
      .bind(15, s.compensated_dph)
      .bind(16, s.rate_in_dps)
      .bind(17, s.gyro_y_dph)
      .bind(18, s.gyro_z_dph)
      .bind(19, s.t1_y_c)
      .bind(20, s.t2_y_c)
      .bind(21, s.t1_z_c)
      .bind(22, s.t2_z_c);
}

// The error of a failed sample insert, in the caller's terms when it is a constraint.
inline StoreError sample_error(Database& db, int rc, std::int64_t run_id, int unit_index, double t_s,
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

}  // namespace detail

using namespace detail;

}  // namespace fogbench::storage
