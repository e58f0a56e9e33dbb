// The Store's models (versions per serial, lineage) and verifications. The other rooms:
// store.cpp (opening, runs), store_samples.cpp (samples, RunData).
#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>

#include "fogbench/storage/models.hpp"
#include "fogbench/storage/store.hpp"
#include "store_rows.hpp"

namespace fogbench::storage {

// ---------------------------------------------------------------- models

namespace {
// The axis a model's JSON names (NewModel::model_json): "" when it names none, nullopt when
// its `axis` is not x, y or z.
std::optional<std::string> model_axis_of(const std::string& model_json) {
  const auto j = nlohmann::json::parse(model_json, nullptr, false);
  if (!j.is_object() || !j.contains("axis")) return std::string();
  const auto& a = j["axis"];
  if (a.is_string() && (a == "x" || a == "y" || a == "z")) return a.get<std::string>();
  return std::nullopt;
}
}  // namespace

StoreResult<ModelRef> Store::put_model(const NewModel& m) {
  assert(db_);
  Database& db = *db_;
  const std::string what = "store a model for serial '" + m.serial + "'";
  if (m.serial.empty())
    return std::unexpected(db.error(StoreErrc::invalid_argument, what + ": empty serial"));
  if (!is_json(m.model_json))
    return std::unexpected(
        db.error(StoreErrc::invalid_argument, what + ": model_json is not valid JSON"));
  const auto axis = model_axis_of(m.model_json);
  if (!axis)
    return std::unexpected(db.error(StoreErrc::invalid_argument,
                                    what + ": model_json's axis is not \"x\", \"y\" or \"z\""));

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
        "terms, axis) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9)");
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
    if (axis->empty()) q.bind_null(9);
    else q.bind(9, *axis);
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

StoreResult<std::optional<ModelRecord>> Store::current_model(std::string_view serial, std::string_view axis) {
  assert(db_);
  Database& db = *db_;
  const std::string what = "read the current model of '" + std::string(serial) + "' axis " + std::string(axis);
  if (axis != "x" && axis != "y" && axis != "z")
    return std::unexpected(db.error(StoreErrc::invalid_argument, what + ": expected axis x, y or z"));
  // A model stored without an axis is a one-axis unit's: its x.
  auto stmt = db.statement("SELECT " FOGBENCH_MODEL_COLUMNS
                           " FROM models WHERE serial = ?1 AND COALESCE(axis, 'x') = ?2 ORDER BY version DESC LIMIT 1");
  if (!stmt) return fail(std::move(stmt));
  Query q(db, *stmt);
  q.bind(1, serial).bind(2, axis);
  auto found = row(db, q, what);
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
      "m.method, m.terms, m.axis FROM chain c JOIN models m ON m.id = c.id ORDER BY c.depth");
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

}  // namespace fogbench::storage
