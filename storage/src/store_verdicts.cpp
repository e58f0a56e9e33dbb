// The serials' verdicts (issue 24, verdict.hpp): the Store's reads and writes of the table
// verdicts. The other rooms: store.cpp (runs), store_models.cpp (models, verifications),
// store_identity.cpp (identity, certificates), store_plans.cpp (plans).
#include "fogbench/storage/store.hpp"
#include "fogbench/storage/verdict.hpp"
#include "store_rows.hpp"

namespace fogbench::storage {

bool is_verdict_name(std::string_view v) {
  return v == "pass" || v == "marginal" || v == "fail" || v == "incomplete";
}
bool is_verdict_rule(std::string_view r) { return r == "plan" || r == "analysis"; }

namespace {

constexpr std::string_view kVerdictColumns =
    "id, serial, run_id, unit_index, model_id, verdict, rule, plan_id, plan_name, plan_sha256, limits_json, "
    "reasons_json, decided_at, axes_json";

VerdictRecord read_verdict(const Query& q) {
  VerdictRecord v;
  v.id = q.int64(0);
  v.serial = q.text(1);
  v.run_id = q.int64(2);
  v.unit_index = static_cast<int>(q.int64(3));
  v.model_id = q.opt_int64(4);
  v.verdict = q.text(5);
  v.rule = q.text(6);
  v.plan_id = q.opt_int64(7);
  v.plan_name = q.text(8);
  v.plan_sha256 = q.text(9);
  v.limits_json = q.text(10);
  v.reasons_json = q.text(11);
  v.decided_at = q.text(12);
  v.axes_json = q.opt_text(13).value_or("");
  return v;
}

// Every row of a verdicts query.
StoreResult<std::vector<VerdictRecord>> read_verdicts(detail::Database& db, Query& q, const std::string& what) {
  std::vector<VerdictRecord> out;
  for (;;) {
    auto got = row(db, q, what);
    if (!got) return fail(std::move(got));
    if (!*got) break;
    out.push_back(read_verdict(q));
  }
  return out;
}

bool is_json_array(std::string_view text) {
  auto j = nlohmann::json::parse(text, nullptr, false);
  return j.is_array();
}
}  // namespace

StoreResult<std::int64_t> Store::put_verdict(const NewVerdict& v) {
  assert(db_);
  Database& db = *db_;
  const std::string what = "store the verdict of serial '" + v.serial + "' (run " + std::to_string(v.run_id) + ")";
  auto bad = [&](const std::string& why) { return std::unexpected(db.error(StoreErrc::invalid_argument, what + ": " + why)); };
  if (!is_verdict_name(v.verdict)) return bad("verdict '" + v.verdict + "' is not pass, marginal, fail or incomplete");
  if (!is_verdict_rule(v.rule)) return bad("rule '" + v.rule + "' is not plan or analysis");
  if ((v.rule == "plan") != v.plan_id.has_value()) return bad("a plan id goes with rule plan, and only with it");
  if (v.rule != "plan" && (!v.plan_name.empty() || !v.plan_sha256.empty()))
    return bad("a plan name or hash with rule " + v.rule);
  if (!is_json_array(v.limits_json)) return bad("limits_json is not a JSON array");
  if (!is_json_array(v.reasons_json)) return bad("reasons_json is not a JSON array");
  if (!v.axes_json.empty() && !is_json_array(v.axes_json)) return bad("axes_json is not a JSON array");
  auto serial = require_unit(db, v.run_id, v.unit_index);
  if (!serial) return fail(std::move(serial));
  if (*serial != v.serial)
    return bad("unit " + std::to_string(v.unit_index) + " of run " + std::to_string(v.run_id) + " is " + *serial);
  if (v.model_id) {
    auto m = get_model(*v.model_id);
    if (!m) return std::unexpected(m.error());
    if (m->serial != v.serial) return bad("model " + std::to_string(*v.model_id) + " is " + m->serial + "'s");
  }
  // The same decision again (a plan runner killed between its decide and its progress save
  // decides on restart what it had decided): the serial's latest row already is this verdict,
  // by the same rule, run, unit, plan and model, with the same limits and reasons: it is
  // returned, not written twice. A serial has one verdict per decision.
  auto latest = latest_verdict(v.serial);
  if (!latest) return std::unexpected(latest.error());
  if (*latest) {
    const VerdictRecord& l = **latest;
    if (l.run_id == v.run_id && l.unit_index == v.unit_index && l.model_id == v.model_id && l.verdict == v.verdict &&
        l.rule == v.rule && l.plan_id == v.plan_id && l.plan_name == v.plan_name && l.plan_sha256 == v.plan_sha256 &&
        l.limits_json == v.limits_json && l.reasons_json == v.reasons_json && l.axes_json == v.axes_json)
      return l.id;
  }
  return with_reserve(db, [&]() -> StoreResult<std::int64_t> {
    auto stmt = db.statement(
        "INSERT INTO verdicts (serial, run_id, unit_index, model_id, verdict, rule, plan_id, plan_name, plan_sha256, "
        "limits_json, reasons_json, decided_at, axes_json) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, "
        "?13)");
    if (!stmt) return fail(std::move(stmt));
    Query q(db, *stmt);
    q.bind(1, v.serial).bind(2, v.run_id).bind(3, v.unit_index).bind(4, v.model_id).bind(5, v.verdict);
    q.bind(6, v.rule).bind(7, v.plan_id).bind(8, v.plan_name).bind(9, v.plan_sha256).bind(10, v.limits_json);
    q.bind(11, v.reasons_json).bind(12, db.now_iso());
    if (v.axes_json.empty()) q.bind_null(13);
    else q.bind(13, v.axes_json);
    if (auto ok = run(db, q, what); !ok) return fail(std::move(ok));
    return static_cast<std::int64_t>(sqlite3_last_insert_rowid(db.handle()));
  });
}

StoreResult<std::optional<VerdictRecord>> Store::latest_verdict(std::string_view serial) {
  assert(db_);
  static const std::string sql =
      "SELECT " + std::string(kVerdictColumns) + " FROM verdicts WHERE serial = ?1 ORDER BY id DESC LIMIT 1";
  auto stmt = db_->statement(sql);
  if (!stmt) return fail(std::move(stmt));
  Query q(*db_, *stmt);
  q.bind(1, serial);
  auto got = row(*db_, q, "read the verdict of serial '" + std::string(serial) + "'");
  if (!got) return fail(std::move(got));
  if (!*got) return std::optional<VerdictRecord>();
  return std::optional<VerdictRecord>(read_verdict(q));
}

StoreResult<std::vector<VerdictRecord>> Store::run_verdicts(std::int64_t run_id) {
  assert(db_);
  static const std::string sql =
      "SELECT " + std::string(kVerdictColumns) + " FROM verdicts WHERE run_id = ?1 ORDER BY unit_index, id";
  auto stmt = db_->statement(sql);
  if (!stmt) return fail(std::move(stmt));
  const std::string what = "read the verdicts of run " + std::to_string(run_id);
  Query q(*db_, *stmt);
  q.bind(1, run_id);
  return read_verdicts(*db_, q, what);
}

StoreResult<std::vector<VerdictRecord>> Store::list_verdicts() {
  assert(db_);
  static const std::string sql = "SELECT " + std::string(kVerdictColumns) + " FROM verdicts ORDER BY id";
  auto stmt = db_->statement(sql);
  if (!stmt) return fail(std::move(stmt));
  Query q(*db_, *stmt);
  return read_verdicts(*db_, q, "read the verdicts");
}

}  // namespace fogbench::storage
