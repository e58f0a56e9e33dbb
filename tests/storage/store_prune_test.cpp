// Retention (issue 28): Store::prune deletes the samples of old runs the plant store has
// received, keeps every other record, and refuses what would lose data.
#include <catch2/catch.hpp>

#include <chrono>
#include <vector>

#include "fogbench/storage/errors.hpp"
#include "fogbench/storage/prune.hpp"
#include "fogbench/storage/runs.hpp"
#include "fogbench/storage/samples.hpp"
#include "fogbench/storage/store.hpp"
#include "store_fixture.hpp"

using namespace fogbench::storage;
using namespace fogbench::storage::testing;

namespace {

// A store whose clock the test sets (seconds since the epoch), so that runs end on known days.
struct ClockedStore {
  std::int64_t now_s = 1767225600;  // 2026-01-01T00:00:00Z
  TempDir tmp;
  Store store;
  ClockedStore() : store(open(tmp, now_s)) {}
  static Store open(const TempDir& tmp, std::int64_t& now_s) {
    OpenOptions o;
    o.clock = [&now_s] { return std::chrono::system_clock::time_point(std::chrono::seconds(now_s)); };
    return open_ok(tmp / "runs.db", o);
  }
  // A two-unit run with n samples per unit, ended in `state` at the clock's time.
  std::int64_t run(int n, RunState state) {
    const auto id = store.create_run(two_unit_run()).value();
    REQUIRE(store.set_run_state(id, RunState::running, "start"));
    std::vector<SampleRow> rows;
    for (int u = 0; u < 2; ++u)
      for (int i = 0; i < n; ++i) rows.push_back(sample(u, i));
    REQUIRE(store.append_samples(id, rows));
    REQUIRE(store.set_run_state(id, state, "end"));
    return id;
  }
  void sent(std::int64_t run_id) {
    const auto entry = store.enqueue_replication(run_id).value();
    REQUIRE(store.mark_replicated(entry));
  }
};

const KeptRun* kept(const PruneReport& r, std::int64_t id) {
  for (const auto& k : r.kept)
    if (k.run_id == id) return &k;
  return nullptr;
}

}  // namespace

TEST_CASE("store prune: the samples of old runs the plant received go, their records stay", "[store][prune]") {
  ClockedStore c;
  const auto old_sent = c.run(100, RunState::completed);
  c.sent(old_sent);
  const auto old_aborted_sent = c.run(10, RunState::aborted);
  c.sent(old_aborted_sent);
  const auto never_sent = c.run(10, RunState::completed);
  const auto waiting = c.run(10, RunState::completed);
  REQUIRE(c.store.enqueue_replication(waiting));
  const auto resumable = c.run(10, RunState::running);
  REQUIRE(c.store.mark_interrupted_runs("power cut"));
  c.now_s += 40 * 86400;  // 2026-02-10
  const auto recent = c.run(10, RunState::completed);
  c.sent(recent);

  PruneOptions o;
  o.before = "2026-02-01";
  o.dry_run = true;
  auto dry = c.store.prune(o);
  REQUIRE(dry);
  CHECK(dry->dry_run);
  CHECK(dry->before == "2026-02-01T00:00:00.000Z");
  REQUIRE(dry->pruned.size() == 2);
  CHECK(dry->samples == 220);
  CHECK(c.store.count_samples(old_sent).value() == 200);  // a dry run changes nothing
  CHECK_FALSE(c.store.get_run(old_sent)->run.pruned_at);

  o.dry_run = false;
  auto r = c.store.prune(o);
  REQUIRE(r);
  REQUIRE(r->pruned.size() == 2);
  CHECK(r->pruned[0].run_id == old_sent);
  CHECK(r->pruned[0].samples == 200);
  CHECK(r->pruned[0].serials == std::vector<std::string>{"FOG-001", "FOG-002"});
  CHECK(r->pruned[0].sent_at.has_value());
  CHECK(r->pruned[1].run_id == old_aborted_sent);
  CHECK(r->samples == 220);
  CHECK(c.store.count_samples(old_sent).value() == 0);
  CHECK(c.store.count_samples(old_aborted_sent).value() == 0);
  // Kept, each with its reason; the recent run is not a candidate at all.
  REQUIRE(kept(*r, never_sent));
  CHECK_THAT(kept(*r, never_sent)->reason, Catch::Contains("never sent to the plant store"));
  REQUIRE(kept(*r, waiting));
  CHECK_THAT(kept(*r, waiting)->reason, Catch::Contains("plant store has not received it"));
  REQUIRE(kept(*r, resumable));
  CHECK_THAT(kept(*r, resumable)->reason, Catch::Contains("may still be resumed"));
  CHECK_FALSE(kept(*r, recent));
  for (const auto id : {never_sent, waiting, resumable, recent}) CHECK(c.store.count_samples(id).value() == 20);

  // The pruned run's record stays, says when and how many, and an event says so.
  auto d = c.store.get_run(old_sent);
  REQUIRE(d);
  CHECK(d->run.state == RunState::completed);
  CHECK(d->run.units.size() == 2);
  REQUIRE(d->run.pruned_at);
  CHECK(*d->run.pruned_at == "2026-02-10T00:00:00.000Z");
  CHECK(d->run.pruned_samples == 200);
  CHECK_THAT(d->events.back().detail_json, Catch::Contains("\"pruned\""));
  // Its samples are refused by name, never read back as an empty run.
  auto exported = c.store.export_run(old_sent, 0);
  REQUIRE_FALSE(exported);
  CHECK(exported.error().code == StoreErrc::pruned);
  CHECK_THAT(exported.error().message, Catch::Contains("run " + std::to_string(old_sent)));
  CHECK_THAT(exported.error().message, Catch::Contains("pruned at 2026-02-10"));
  CHECK(c.store.get_samples(old_sent, 1, 0, 10).error().code == StoreErrc::pruned);
  // Sent again, it would replace the plant's copy with no samples: refused.
  CHECK(c.store.enqueue_replication(old_sent).error().code == StoreErrc::pruned);

  // A second prune finds nothing more to do.
  auto again = c.store.prune(o);
  REQUIRE(again);
  CHECK(again->pruned.empty());

  // --include-unreplicated takes the runs never sent and those waiting, not the resumable one.
  o.include_unreplicated = true;
  auto all = c.store.prune(o);
  REQUIRE(all);
  REQUIRE(all->pruned.size() == 2);
  CHECK(all->pruned[0].run_id == never_sent);
  CHECK_FALSE(all->pruned[0].sent_at);
  CHECK(all->pruned[1].run_id == waiting);
  CHECK(kept(*all, resumable));
  CHECK(c.store.count_samples(resumable).value() == 20);
  CHECK(c.store.count_samples(recent).value() == 20);
}

TEST_CASE("store prune: a prune cut short is finished by the next, whatever its date, and large runs go in chunks",
          "[store][prune]") {
  ClockedStore c;
  const auto big = c.run(60000, RunState::completed);  // 120,000 rows: three delete chunks
  c.sent(big);
  {
    // What a prune killed after marking the run leaves: marked, with its samples.
    Raw raw(c.tmp / "runs.db");
    raw.exec("UPDATE runs SET pruned_at = '2026-01-01T00:00:00.000Z', pruned_samples = 120000 WHERE id = " +
             std::to_string(big));
  }
  PruneOptions o;
  o.before = "2025-01-01";  // before the run ended: only the unfinished prune is taken
  auto r = c.store.prune(o);
  REQUIRE(r);
  REQUIRE(r->pruned.size() == 1);
  CHECK(r->pruned[0].run_id == big);
  CHECK(r->samples == 120000);
  CHECK(c.store.count_samples(big).value() == 0);
  CHECK(c.store.get_run(big)->run.pruned_samples == 120000);  // the mark of the first prune stays
}

TEST_CASE("store prune: a malformed date is refused naming what is wrong, nothing touched", "[store][prune]") {
  ClockedStore c;
  const auto id = c.run(5, RunState::completed);
  c.sent(id);
  for (const auto& [date, says] : std::vector<std::pair<std::string, std::string>>{
           {"2026-13-01", "month 13 is not 1..12"},
           {"2026-02-00", "day 0 is not 1..31"},
           {"yesterday", "is not a date"},
           {"2026-02-01 10:00", "is not a date"},
           {"2026-02-01T25:00:00Z", "time of day"},
           {"2026-02-01T10:00:00+01:00", "is not a date"}}) {
    PruneOptions o;
    o.before = date;
    auto r = c.store.prune(o);
    INFO(date);
    REQUIRE_FALSE(r);
    CHECK(r.error().code == StoreErrc::invalid_argument);
    CHECK_THAT(r.error().message, Catch::Contains(says));
  }
  CHECK(c.store.count_samples(id).value() == 10);
  PruneOptions ok;
  ok.before = "2026-01-01T00:00:01Z";  // the run ended at 00:00:00.000
  REQUIRE(c.store.prune(ok)->pruned.size() == 1);
}

TEST_CASE("store vacuum: the pages a prune freed go back to the filesystem, the kept runs read as before",
          "[store][prune]") {
  ClockedStore c;
  const auto old_sent = c.run(40000, RunState::completed);  // 80,000 rows, some MB
  c.sent(old_sent);
  const auto kept_run = c.run(300, RunState::completed);
  PruneOptions o;
  o.before = "2026-01-02";
  REQUIRE(c.store.prune(o)->samples == 80000);
  auto v = c.store.vacuum();
  REQUIRE(v);
  INFO("before " << v->bytes_before << " after " << v->bytes_after << " live " << v->live_bytes);
  // The file held the deleted rows' pages; after, it is about its live pages (a few hundred kB).
  CHECK(v->bytes_after < v->bytes_before / 4);
  CHECK(v->live_bytes <= v->bytes_before);
  CHECK(v->bytes_after <= v->live_bytes + 64 * 1024);
  CHECK(v->free_bytes > 0);
  CHECK(c.store.count_samples(kept_run).value() == 600);
  CHECK(c.store.get_run(old_sent)->run.pruned_samples == 80000);
  // A second vacuum has nothing to give back.
  auto again = c.store.vacuum();
  REQUIRE(again);
  CHECK(again->bytes_after <= again->bytes_before);
  CHECK(again->bytes_before - again->bytes_after < 64 * 1024);
}
