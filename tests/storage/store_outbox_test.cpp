// The plant outbox and the units' lots (storage migration 4, issue 14).
#include <catch2/catch.hpp>

#include "fogbench/storage/errors.hpp"
#include "fogbench/storage/outbox.hpp"
#include "fogbench/storage/runs.hpp"
#include "fogbench/storage/store.hpp"

using namespace fogbench::storage;

namespace {
Store memory() {
  auto s = Store::open(":memory:");
  REQUIRE(s);
  return std::move(*s);
}
std::int64_t completed_run(Store& s, std::vector<std::optional<std::string>> lots = {}) {
  NewRun nr;
  nr.profile_name = "p";
  nr.unit_serials = {"A", "B"};
  nr.unit_lots = std::move(lots);
  auto id = s.create_run(nr);
  REQUIRE(id);
  REQUIRE(s.set_run_state(*id, RunState::completed, "done"));
  return *id;
}
}  // namespace

TEST_CASE("store outbox: entries in order, one per waiting run, failures kept at the head, sent ones counted",
          "[store][outbox]") {
  Store s = memory();
  const auto a = completed_run(s), b = completed_run(s);
  auto ea = s.enqueue_replication(a);
  REQUIRE(ea);
  CHECK(*s.enqueue_replication(a) == *ea);  // already waiting: the same entry
  REQUIRE(s.enqueue_replication(b));
  CHECK(s.enqueue_replication(999).error().code == StoreErrc::not_found);
  auto st = s.outbox_status();
  CHECK(st->depth == 2);
  CHECK(st->sent == 0);
  auto head = s.pending_replications(10);
  REQUIRE(head->size() == 2);
  CHECK(head->at(0).run_id == a);
  CHECK(head->at(1).run_id == b);
  REQUIRE(s.mark_replication_failed(*ea, "the plant refused the login"));
  REQUIRE(s.mark_replication_failed(*ea, "the plant is gone"));
  st = s.outbox_status();
  CHECK(st->attempts == 2);
  CHECK(st->last_error == "the plant is gone");
  CHECK(s.pending_replications(1)->front().run_id == a);  // keeps its place
  REQUIRE(s.mark_replicated(*ea));
  CHECK(s.mark_replicated(*ea).error().code == StoreErrc::not_found);  // sent once
  st = s.outbox_status();
  CHECK(st->depth == 1);
  CHECK(st->sent == 1);
  CHECK(st->last_sent_at.has_value());
  CHECK(s.pending_replications(1)->front().run_id == b);
  // Queued again once sent: a new entry behind the others.
  auto again = s.enqueue_replication(a);
  REQUIRE(again);
  CHECK(*again != *ea);
  CHECK(s.pending_replications(10)->back().run_id == a);
}

TEST_CASE("store outbox: completed runs never queued are queued once, others are not", "[store][outbox]") {
  Store s = memory();
  const auto a = completed_run(s), b = completed_run(s);
  NewRun nr;
  nr.profile_name = "p";
  nr.unit_serials = {"A"};
  const auto aborted = s.create_run(nr).value();
  REQUIRE(s.set_run_state(aborted, RunState::aborted, "stop"));
  REQUIRE(s.enqueue_replication(a));
  CHECK(*s.enqueue_unqueued_completed_runs() == 1);  // b only
  CHECK(*s.enqueue_unqueued_completed_runs() == 0);
  auto head = s.pending_replications(10);
  REQUIRE(head->size() == 2);
  CHECK(head->at(1).run_id == b);
}

TEST_CASE("store lots: each unit's lot is kept as given, quotes and all, too long is refused", "[store][outbox]") {
  Store s = memory();
  const auto id = completed_run(s, {std::nullopt, std::string("L-\"7\" O'Neil")});
  auto d = s.get_run(id);
  REQUIRE(d);
  CHECK_FALSE(d->run.units[0].lot.has_value());
  CHECK(d->run.units[1].lot == std::optional<std::string>("L-\"7\" O'Neil"));
  NewRun nr;
  nr.profile_name = "p";
  nr.unit_serials = {"A"};
  nr.unit_lots = {std::string(65, 'x')};
  auto bad = s.create_run(nr);
  REQUIRE_FALSE(bad);
  CHECK(bad.error().code == StoreErrc::constraint);
  CHECK(s.list_runs()->size() == 1);  // nothing of the refused run
}
