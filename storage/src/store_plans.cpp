// The Store's qualification plans, their queue and their audit trail (schema version 6,
// docs/plans.md). The other rooms: store.cpp (runs), store_samples.cpp, store_models.cpp.
#include <nlohmann/json.hpp>

#include "fogbench/storage/plans.hpp"
#include "fogbench/storage/store.hpp"
#include "store_rows.hpp"

namespace fogbench::storage {

namespace {

#define FOGBENCH_PLAN_COLUMNS \
  "id, name, source, plan_text, units_json, state, queue_pos, created_at, started_at, ended_at, reason, progress_json, " \
  "operator, operator_source, lots_json, slots_json"

PlanRecord read_plan(const Query& q) {
  PlanRecord p;
  p.id = q.int64(0);
  p.name = q.text(1);
  p.source = q.text(2);
  p.plan_text = q.text(3);
  for (const auto& s : nlohmann::json::parse(q.text(4), nullptr, false))
    if (s.is_string()) p.units.push_back(s.get<std::string>());
  p.state = q.text(5);
  p.queue_pos = q.opt_int64(6);
  p.created_at = q.text(7);
  p.started_at = q.opt_text(8);
  p.ended_at = q.opt_text(9);
  p.reason = q.text(10);
  p.progress_json = q.text(11);
  p.operator_name = q.text(12);
  p.operator_source = q.text(13);
  const auto lots = nlohmann::json::parse(q.text(14), nullptr, false);
  if (lots.is_object())
    for (const auto& [serial, lot] : lots.items())
      if (lot.is_string()) p.lots[serial] = lot.get<std::string>();
  const auto slots = nlohmann::json::parse(q.text(15), nullptr, false);
  if (slots.is_object())
    for (const auto& [serial, slot] : slots.items())
      if (slot.is_string()) p.slots[serial] = slot.get<std::string>();
  return p;
}

bool end_state(std::string_view s) { return s == "completed" || s == "aborted" || s == "failed"; }

StoreResult<std::int64_t> insert_plan_event(Database& db, std::optional<std::int64_t> plan_id, std::string_view kind,
                                            std::string_view detail, std::string_view what) {
  if (!is_json(json_or_empty_object(detail)))
    return std::unexpected(db.error(StoreErrc::invalid_argument, std::string(what) + ": detail is not JSON"));
  auto stmt = db.statement("INSERT INTO plan_events (at, plan_id, kind, detail_json) VALUES (?1, ?2, ?3, ?4)");
  if (!stmt) return fail(std::move(stmt));
  Query q(db, *stmt);
  q.bind(1, db.now_iso()).bind(2, plan_id).bind(3, kind).bind(4, json_or_empty_object(detail));
  if (auto ok = run(db, q, what); !ok) return fail(std::move(ok));
  return sqlite3_last_insert_rowid(db.handle());
}

}  // namespace

StoreResult<std::int64_t> Store::create_plan(const NewPlan& p, std::string_view event_kind,
                                             std::string_view event_detail_json) {
  assert(db_);
  Database& db = *db_;
  const std::string what = "store plan '" + p.name + "'";
  if (p.state != "queued" && p.state != "running")
    return std::unexpected(db.error(StoreErrc::invalid_argument, what + ": a new plan is queued or running"));
  Transaction tx(db);
  if (auto ok = tx.begin(what); !ok) return fail(std::move(ok));
  std::optional<std::int64_t> pos;
  if (p.state == "queued") {
    auto stmt = db.statement("SELECT COALESCE(MAX(queue_pos), 0) + 1 FROM plans WHERE state = 'queued'");
    if (!stmt) return fail(std::move(stmt));
    Query q(db, *stmt);
    auto got = row(db, q, what);
    if (!got) return fail(std::move(got));
    pos = q.int64(0);
  }
  {
    auto stmt = db.statement(
        "INSERT INTO plans (name, source, plan_text, units_json, state, queue_pos, created_at, started_at, "
        "operator, operator_source, lots_json, slots_json) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12)");
    if (!stmt) return fail(std::move(stmt));
    Query q(db, *stmt);
    const std::string now = db.now_iso();
    q.bind(1, p.name).bind(2, p.source).bind(3, p.plan_text).bind(4, nlohmann::json(p.units).dump())
        .bind(5, p.state).bind(6, pos).bind(7, now);
    if (p.state == "running") q.bind(8, now);
    else q.bind_null(8);
    q.bind(9, p.operator_name).bind(10, p.operator_source).bind(11, nlohmann::json(p.lots).dump());
    q.bind(12, nlohmann::json(p.slots).dump());
    if (auto ok = run(db, q, what); !ok) return fail(std::move(ok));
  }
  const std::int64_t id = sqlite3_last_insert_rowid(db.handle());
  if (auto ok = insert_plan_event(db, id, event_kind, event_detail_json, what); !ok) return fail(std::move(ok));
  if (auto ok = tx.commit(what); !ok) return fail(std::move(ok));
  return id;
}

StoreResult<void> Store::update_plan(std::int64_t plan_id, std::string_view state, std::string_view reason,
                                     std::string_view progress_json) {
  assert(db_);
  Database& db = *db_;
  const std::string what = "update plan " + std::to_string(plan_id);
  if (!is_json(progress_json))
    return std::unexpected(db.error(StoreErrc::invalid_argument, what + ": progress is not JSON"));
  auto stmt = db.statement(
      "UPDATE plans SET state = ?2, reason = ?3, progress_json = ?4, "
      "queue_pos = CASE WHEN ?2 = 'queued' THEN queue_pos END, "
      "started_at = CASE WHEN ?2 = 'running' AND started_at IS NULL THEN ?5 ELSE started_at END, "
      "ended_at = CASE WHEN ?6 THEN ?5 ELSE ended_at END WHERE id = ?1");
  if (!stmt) return fail(std::move(stmt));
  Query q(db, *stmt);
  q.bind(1, plan_id).bind(2, state).bind(3, reason).bind(4, progress_json).bind(5, db.now_iso())
      .bind(6, static_cast<std::int64_t>(end_state(state)));
  if (auto ok = run(db, q, what); !ok) return fail(std::move(ok));
  if (sqlite3_changes(db.handle()) == 0)
    return std::unexpected(db.error(StoreErrc::not_found, "no plan " + std::to_string(plan_id)));
  return {};
}

StoreResult<PlanRecord> Store::get_plan(std::int64_t plan_id) {
  assert(db_);
  Database& db = *db_;
  auto stmt = db.statement("SELECT " FOGBENCH_PLAN_COLUMNS " FROM plans WHERE id = ?1");
  if (!stmt) return fail(std::move(stmt));
  Query q(db, *stmt);
  q.bind(1, plan_id);
  const std::string what = "plan " + std::to_string(plan_id);
  auto found = row(db, q, "read " + what);
  if (!found) return fail(std::move(found));
  if (!*found) return std::unexpected(db.error(StoreErrc::not_found, "no " + what));
  return read_plan(q);
}

StoreResult<std::vector<PlanRecord>> Store::list_plans(std::optional<std::string_view> state) {
  assert(db_);
  Database& db = *db_;
  auto stmt = db.statement("SELECT " FOGBENCH_PLAN_COLUMNS
                           " FROM plans WHERE (?1 IS NULL OR state = ?1) ORDER BY queue_pos IS NULL, queue_pos, id");
  if (!stmt) return fail(std::move(stmt));
  Query q(db, *stmt);
  q.bind(1, state);
  std::vector<PlanRecord> out;
  for (;;) {
    auto got = row(db, q, "list plans");
    if (!got) return fail(std::move(got));
    if (!*got) break;
    out.push_back(read_plan(q));
  }
  return out;
}

StoreResult<void> Store::set_queue(const std::vector<std::int64_t>& ids, std::optional<std::int64_t> removed,
                                   std::string_view event_kind, std::string_view event_detail_json) {
  assert(db_);
  Database& db = *db_;
  const std::string what = "change the plan queue";
  Transaction tx(db);
  if (auto ok = tx.begin(what); !ok) return fail(std::move(ok));
  std::int64_t pos = 1;
  for (std::int64_t id : ids) {
    auto stmt = db.statement("UPDATE plans SET queue_pos = ?2 WHERE id = ?1 AND state = 'queued'");
    if (!stmt) return fail(std::move(stmt));
    Query q(db, *stmt);
    q.bind(1, id).bind(2, pos++);
    if (auto ok = run(db, q, what); !ok) return fail(std::move(ok));
    if (sqlite3_changes(db.handle()) == 0)
      return std::unexpected(db.error(StoreErrc::not_found, "plan " + std::to_string(id) + " is not queued"));
  }
  if (removed) {
    auto stmt = db.statement(
        "UPDATE plans SET state = 'aborted', reason = 'removed from the queue', queue_pos = NULL, ended_at = ?2 "
        "WHERE id = ?1 AND state = 'queued'");
    if (!stmt) return fail(std::move(stmt));
    Query q(db, *stmt);
    q.bind(1, *removed).bind(2, db.now_iso());
    if (auto ok = run(db, q, what); !ok) return fail(std::move(ok));
    if (sqlite3_changes(db.handle()) == 0)
      return std::unexpected(db.error(StoreErrc::not_found, "plan " + std::to_string(*removed) + " is not queued"));
  }
  if (auto ok = insert_plan_event(db, removed, event_kind, event_detail_json, what); !ok) return fail(std::move(ok));
  if (auto ok = tx.commit(what); !ok) return fail(std::move(ok));
  return {};
}

StoreResult<std::int64_t> Store::add_plan_event(std::optional<std::int64_t> plan_id, std::string_view kind,
                                                std::string_view detail_json) {
  assert(db_);
  return insert_plan_event(*db_, plan_id, kind, detail_json, "add a plan event");
}

StoreResult<std::vector<PlanEvent>> Store::plan_events(std::optional<std::int64_t> plan_id) {
  assert(db_);
  Database& db = *db_;
  auto stmt = db.statement(
      "SELECT id, at, plan_id, kind, detail_json FROM plan_events WHERE (?1 IS NULL OR plan_id = ?1) ORDER BY id");
  if (!stmt) return fail(std::move(stmt));
  Query q(db, *stmt);
  q.bind(1, plan_id);
  std::vector<PlanEvent> out;
  for (;;) {
    auto got = row(db, q, "read plan events");
    if (!got) return fail(std::move(got));
    if (!*got) break;
    out.push_back(PlanEvent{q.int64(0), q.text(1), q.opt_int64(2), q.text(3), q.text(4)});
  }
  return out;
}

}  // namespace fogbench::storage
