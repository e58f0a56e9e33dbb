// The Store's samples: a second's rows appended in one transaction, pages of them, and a run's
// unit as a RunData (export) or from one (import). The other rooms: store.cpp (opening, runs),
// store_models.cpp (models, verifications).
#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>

#include "fogbench/storage/identity.hpp"
#include "fogbench/storage/runs.hpp"
#include "fogbench/storage/samples.hpp"
#include "fogbench/storage/store.hpp"
#include "store_identity.hpp"
#include "store_rows.hpp"

namespace fogbench::storage {

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
  if (auto ok = require_samples_kept(db, run_id); !ok) return fail(std::move(ok));
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

StoreResult<model::RunData> Store::export_run(std::int64_t run_id, int unit_index) {
  return export_run(run_id, unit_index, ExportOptions{});
}

StoreResult<model::RunData> Store::export_run(std::int64_t run_id, int unit_index,
                                              const ExportOptions& options) {
  assert(db_);
  Database& db = *db_;
  const std::string label = "unit " + std::to_string(unit_index) + " of " + run_label(run_id);
  auto serial = require_unit(db, run_id, unit_index);
  if (!serial) return fail(std::move(serial));
  if (auto ok = require_samples_kept(db, run_id); !ok) return fail(std::move(ok));
  // A three-axis unit's y and z are exported with it; a one-axis unit's rows as before.
  bool three_axis = false;
  {
    auto stmt = db.statement("SELECT axes FROM run_units WHERE run_id = ?1 AND unit_index = ?2");
    if (!stmt) return fail(std::move(stmt));
    Query q(db, *stmt);
    q.bind(1, run_id).bind(2, unit_index);
    auto got = row(db, q, "read the axes of " + label);
    if (!got) return fail(std::move(got));
    three_axis = q.int64(0) == 3;
  }
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
       has_flags = false, has_power_on = false, has_compensated = false,
       has_rate_in = false, has_axis_thermistors = false;
  std::size_t settle_skipped = 0;
  bool in_leading_settle = !options.include_settle;

  auto stmt = db.statement(
      "SELECT t_s, gyro_dph, t1_c, t2_c, setpoint_c, chamber_c, phase, step, flags, since_power_on_s, "
      "compensated_dph, rate_in_dps, gyro_y_dph, gyro_z_dph, t1_y_c, t2_y_c, t1_z_c, t2_z_c FROM samples "
      "WHERE run_id = ?1 AND unit_index = ?2 "
      "ORDER BY t_s");
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
    has_compensated |= !q.is_null(10);
    d.compensated_dph.push_back(q.real(10));
    has_rate_in |= !q.is_null(11);
    d.rate_in_dps.push_back(q.real(11));
    if (three_axis) {
      d.gyro_y_dph.push_back(q.real(12));
      d.gyro_z_dph.push_back(q.real(13));
      // y's and z's own thermistors, where recorded (x's are t1_c, t2_c).
      for (int c = 14; c < 18; ++c) has_axis_thermistors |= !q.is_null(c);
      d.axis_t1_c[1].push_back(q.real(14));
      d.axis_t2_c[1].push_back(q.real(15));
      d.axis_t1_c[2].push_back(q.real(16));
      d.axis_t2_c[2].push_back(q.real(17));
    }
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
  drop(has_compensated, d.compensated_dph);
  drop(has_rate_in, d.rate_in_dps);
  if (has_axis_thermistors) {
    d.axis_t1_c[0] = d.t1_c;
    d.axis_t2_c[0] = d.t2_c;
  } else {
    for (std::size_t k = 1; k < 3; ++k) {
      drop(false, d.axis_t1_c[k]);
      drop(false, d.axis_t2_c[k]);
    }
  }
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
  // Stored names as at every other entry (docs/reliability.md "Issue 27 checklist").
  if (auto why = check_stored_text("serial", options.serial, kMaxNameBytes); !why.empty()) return invalid(why);
  if (auto why = check_stored_text("profile_name", options.profile_name, kMaxNameBytes); !why.empty()) return invalid(why);
  if (options.lot) {
    if (options.lot->empty()) return invalid("the lot is empty (leave it out for a unit without one)");
    if (auto why = check_stored_text("lot", *options.lot, 64); !why.empty()) return invalid(why);
  }
  if (n == 0) return invalid("no samples");
  const std::pair<std::string_view, std::size_t> sizes[] = {
      {"gyro_dph", data.gyro_dph.size()},     {"t1_c", data.t1_c.size()},
      {"t2_c", data.t2_c.size()},             {"setpoint_c", data.setpoint_c.size()},
      {"chamber_c", data.chamber_c.size()},   {"phase", data.phase.size()},
      {"step", data.step.size()},             {"flags", data.flags.size()},
      {"since_power_on_s", data.since_power_on_s.size()}, {"compensated_dph", data.compensated_dph.size()},
      {"rate_in_dps", data.rate_in_dps.size()}, {"gyro_y_dph", data.gyro_y_dph.size()},
      {"gyro_z_dph", data.gyro_z_dph.size()}};
  for (std::size_t c = 0; c < std::size(sizes); ++c) {
    const bool required = c < 3;
    const auto [name, size] = sizes[c];
    if (size != n && (required || size != 0))
      return invalid(std::string(name) + " has " + std::to_string(size) +
                     " values but time_s has " + std::to_string(n));
  }
  if (data.gyro_y_dph.size() != data.gyro_z_dph.size())
    return invalid("gyro_y_dph and gyro_z_dph go together (a three-axis unit's y and z): " +
                   std::to_string(data.gyro_y_dph.size()) + " and " + std::to_string(data.gyro_z_dph.size()) + " values");
  // Per-axis thermistors: a three-axis unit's, all six one per sample (x's the run's t1_c, t2_c).
  if (data.has_axis_thermistors()) {
    if (!data.has_axes())
      return invalid("the run has per-axis thermistors (t1_y_c, t2_y_c, t1_z_c, t2_z_c) but no y and z outputs "
                     "(gyro_y_dph, gyro_z_dph): per-axis thermistors belong to a three-axis unit");
    static constexpr const char* kAxisColumns[2][3] = {{"t1_c", "t1_y_c", "t1_z_c"}, {"t2_c", "t2_y_c", "t2_z_c"}};
    for (std::size_t k = 1; k < 3; ++k)
      for (std::size_t w = 0; w < 2; ++w) {
        const auto& col = w == 0 ? data.axis_t1_c[k] : data.axis_t2_c[k];
        if (col.size() != n)
          return invalid(std::string(kAxisColumns[w][k]) + " has " + std::to_string(col.size()) + " values but time_s has " +
                         std::to_string(n));
      }
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
        "INSERT INTO runs (created_at, profile_name, purpose, state, state_reason, config_json, profile_text) "
        "VALUES (?1, ?2, ?3, 'completed', ?4, ?5, ?6)");
    if (!stmt) return fail(std::move(stmt));
    Query q(db, *stmt);
    const std::string reason = "imported from " + data.name;
    q.bind(1, db.now_iso())
        .bind(2, options.profile_name)
        .bind(3, to_string(options.purpose))
        .bind(4, reason)
        .bind(5, config)
        .bind(6, options.profile_text);
    if (auto ok = run(db, q, what); !ok) return fail(std::move(ok));
  }
  const std::int64_t id = sqlite3_last_insert_rowid(db.handle());
  {
    auto stmt =
        db.statement("INSERT INTO run_units (run_id, unit_index, serial, lot, axes) VALUES (?1, ?2, ?3, ?4, ?5)");
    if (!stmt) return fail(std::move(stmt));
    Query q(db, *stmt);
    q.bind(1, id).bind(2, 0).bind(3, options.serial).bind(4, options.lot).bind(5, data.has_axes() ? 3 : 1);
    if (auto ok = run(db, q, what); !ok) return fail(std::move(ok));
  }
  {
    auto stmt = db.statement(kInsertSample);
    if (!stmt) return fail(std::move(stmt));
    Query q(db, *stmt);
    // Columns the data lacks stay NULL, so export_run gives back the same columns.
    q.bind(1, id).bind(2, 0).bind_null(4).bind_null(8).bind_null(19).bind_null(20).bind_null(21).bind_null(22);
    for (std::size_t i = 0; i < n; ++i) {
      q.bind(3, data.time_s[i]).bind(7, data.gyro_dph[i]).bind(9, data.t1_c[i]).bind(10, data.t2_c[i]);
      if (data.has_setpoint()) q.bind(5, data.setpoint_c[i]);
      if (data.has_chamber()) q.bind(6, data.chamber_c[i]);
      if (data.has_phase()) q.bind(11, static_cast<int>(data.phase[i]));
      if (data.has_step()) q.bind(12, data.step[i]);
      if (data.has_flags()) q.bind(13, static_cast<int>(data.flags[i]));
      if (data.has_power_on()) q.bind(14, data.since_power_on_s[i]);
      if (data.has_compensated()) q.bind(15, data.compensated_dph[i]);
      if (data.has_rate_in()) q.bind(16, data.rate_in_dps[i]);
      if (data.has_axes()) q.bind(17, data.gyro_y_dph[i]).bind(18, data.gyro_z_dph[i]);
      if (data.has_axis_thermistors()) {
        q.bind(19, data.axis_t1_c[1][i]).bind(20, data.axis_t2_c[1][i]);
        q.bind(21, data.axis_t1_c[2][i]).bind(22, data.axis_t2_c[2][i]);
      }
      if (int rc = q.step(); rc != SQLITE_DONE)
        return std::unexpected(sample_error(db, rc, id, 0, data.time_s[i], what));
      q.reset();
    }
  }
  if (options.identity) {
    RunIdentity identity = *options.identity;
    identity.units.resize(1);  // the file's unit is the run's unit 0
    identity.units[0].unit_index = 0;
    identity.units[0].serial = options.serial;
    if (auto ok = insert_identity(db, id, identity, what); !ok) return fail(std::move(ok));
  }
  const std::string detail =
      nlohmann::json{{"imported_from", data.name}, {"samples", n}, {"serial", options.serial}}
          .dump();
  if (auto ok = insert_event(db, id, std::nullopt, EventKind::note, detail); !ok)
    return fail(std::move(ok));
  if (auto ok = tx.commit(what); !ok) return fail(std::move(ok));
  return id;
}

}  // namespace fogbench::storage
