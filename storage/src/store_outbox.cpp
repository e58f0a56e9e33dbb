// The Store's plant outbox (issue 14): the completed runs waiting to be replicated to the plant's
// PostgreSQL by fogbench::plant, kept here so that an outage of the network or of the plant
// store loses nothing. The other rooms: store.cpp (opening, runs), store_samples.cpp,
// store_models.cpp.
#include "fogbench/storage/outbox.hpp"
#include "fogbench/storage/store.hpp"
#include "store_rows.hpp"

namespace fogbench::storage {

StoreResult<std::int64_t> Store::enqueue_replication(std::int64_t run_id) {
  assert(db_);
  Database& db = *db_;
  const std::string what = "queue " + run_label(run_id) + " for the plant";
  Transaction tx(db);
  if (auto ok = tx.begin(what); !ok) return fail(std::move(ok));
  if (auto ok = require_run(db, run_id); !ok) return fail(std::move(ok));
  // A pruned run sent again would replace the plant's copy of its samples with none.
  if (auto ok = require_samples_kept(db, run_id); !ok) return fail(std::move(ok));
  auto find = db.statement("SELECT id FROM plant_outbox WHERE run_id = ?1 AND sent_at IS NULL");
  if (!find) return fail(std::move(find));
  {
    Query q(db, *find);
    q.bind(1, run_id);
    auto got = row(db, q, what);
    if (!got) return fail(std::move(got));
    if (*got) return q.int64(0);  // already waiting: the transaction rolls back, nothing written
  }
  auto ins = db.statement("INSERT INTO plant_outbox (run_id, queued_at) VALUES (?1, ?2)");
  if (!ins) return fail(std::move(ins));
  {
    Query q(db, *ins);
    q.bind(1, run_id).bind(2, db.now_iso());
    if (auto ok = run(db, q, what); !ok) return fail(std::move(ok));
  }
  const std::int64_t id = sqlite3_last_insert_rowid(db.handle());
  if (auto ok = tx.commit(what); !ok) return fail(std::move(ok));
  return id;
}

StoreResult<std::int64_t> Store::enqueue_unqueued_completed_runs() {
  assert(db_);
  Database& db = *db_;
  const std::string what = "queue the completed runs never sent to the plant";
  auto stmt = db.statement(
      "INSERT INTO plant_outbox (run_id, queued_at) "
      "SELECT id, ?1 FROM runs WHERE state = 'completed' "
      "AND pruned_at IS NULL AND id NOT IN (SELECT run_id FROM plant_outbox) ORDER BY ended_at, id");
  if (!stmt) return fail(std::move(stmt));
  Query q(db, *stmt);
  q.bind(1, db.now_iso());
  if (auto ok = run(db, q, what); !ok) return fail(std::move(ok));
  return static_cast<std::int64_t>(sqlite3_changes(db.handle()));
}

StoreResult<std::vector<OutboxEntry>> Store::pending_replications(std::int64_t limit) {
  assert(db_);
  Database& db = *db_;
  auto stmt = db.statement(
      "SELECT id, run_id, queued_at, attempts, last_error FROM plant_outbox "
      "WHERE sent_at IS NULL ORDER BY id LIMIT ?1");
  if (!stmt) return fail(std::move(stmt));
  Query q(db, *stmt);
  q.bind(1, limit);
  std::vector<OutboxEntry> out;
  int rc;
  while ((rc = q.step()) == SQLITE_ROW)
    out.push_back(OutboxEntry{q.int64(0), q.int64(1), q.text(2), static_cast<int>(q.int64(3)), q.text(4)});
  if (rc != SQLITE_DONE) return std::unexpected(db.error(rc, "read the plant outbox"));
  return out;
}

StoreResult<void> Store::mark_replicated(std::int64_t entry_id) {
  assert(db_);
  Database& db = *db_;
  const std::string what = "mark plant outbox entry " + std::to_string(entry_id) + " sent";
  auto stmt = db.statement(
      "UPDATE plant_outbox SET sent_at = ?2, last_attempt_at = ?2 WHERE id = ?1 AND sent_at IS NULL");
  if (!stmt) return fail(std::move(stmt));
  Query q(db, *stmt);
  const std::string now = db.now_iso();
  q.bind(1, entry_id).bind(2, now);
  if (auto ok = run(db, q, what); !ok) return ok;
  if (sqlite3_changes(db.handle()) != 1)
    return std::unexpected(db.error(StoreErrc::not_found, what + ": no such waiting entry"));
  return {};
}

StoreResult<void> Store::mark_replication_failed(std::int64_t entry_id, std::string_view error) {
  assert(db_);
  Database& db = *db_;
  const std::string what = "note a failed attempt of plant outbox entry " + std::to_string(entry_id);
  auto stmt = db.statement(
      "UPDATE plant_outbox SET attempts = attempts + 1, last_error = ?2, last_attempt_at = ?3 "
      "WHERE id = ?1 AND sent_at IS NULL");
  if (!stmt) return fail(std::move(stmt));
  Query q(db, *stmt);
  q.bind(1, entry_id).bind(2, error).bind(3, db.now_iso());
  return run(db, q, what);
}

StoreResult<OutboxStatus> Store::outbox_status() {
  assert(db_);
  Database& db = *db_;
  const std::string what = "read the plant outbox";
  OutboxStatus s;
  {
    auto stmt = db.statement(
        "SELECT (SELECT count(*) FROM plant_outbox WHERE sent_at IS NULL), "
        "(SELECT count(*) FROM plant_outbox WHERE sent_at IS NOT NULL), "
        "(SELECT max(sent_at) FROM plant_outbox)");
    if (!stmt) return fail(std::move(stmt));
    Query q(db, *stmt);
    auto got = row(db, q, what);
    if (!got) return fail(std::move(got));
    s.depth = q.int64(0);
    s.sent = q.int64(1);
    s.last_sent_at = q.opt_text(2);
  }
  auto head = db.statement(
      "SELECT queued_at, attempts, last_error FROM plant_outbox WHERE sent_at IS NULL ORDER BY id LIMIT 1");
  if (!head) return fail(std::move(head));
  Query q(db, *head);
  auto got = row(db, q, what);
  if (!got) return fail(std::move(got));
  if (*got) {
    s.oldest_queued_at = q.text(0);
    s.attempts = static_cast<int>(q.int64(1));
    s.last_error = q.text(2);
  }
  return s;
}

}  // namespace fogbench::storage
