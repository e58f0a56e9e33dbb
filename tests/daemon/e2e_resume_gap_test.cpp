// A resume after a long downtime (issue 27 point 2): the gap's seconds (tens of thousands) are
// written by the sample writer's thread, not on the event loop, so `status` answers while they
// are; and the gap is written once, a resume killed while writing it completed by the next one.
// The downtime is made by moving the stored seconds' wall times back (the daemon measures the
// time away from the last second it read).
#include "live_bench.hpp"

#include <sqlite3.h>

#include "fogbench/model/run.hpp"
#include "fogbench/storage/samples.hpp"
#include "fogbench/storage/store.hpp"

using namespace fogbench;
using namespace fogbench::daemon::test;
using namespace fogbench::daemon::test::live;
using nlohmann::json;
using namespace std::chrono_literals;

namespace {

// Starts a run on both units, lets it store a few seconds, kills the daemon, and moves the
// stored seconds back by `away_wall_s` of wall time; the run's id.
std::int64_t run_then_kill(LiveBench& bench, double away_wall_s) {
  std::int64_t run = 0;
  {
    LineClient c(bench.socket());
    REQUIRE(c.ok());
    run = bench.start_run(c, "short", {"SIM-0001", "SIM-0002"});
    auto s = bench.wait_status(c, [](const json& r) {
      return r["run"].is_object() && r["run"]["elapsed_s"].get<double>() >= 30.0;
    }, 60s);
    REQUIRE(s["result"]["run"]["elapsed_s"].get<double>() >= 30.0);
  }
  bench.daemon->kill_now();
  sqlite3* db = nullptr;
  REQUIRE(sqlite3_open((bench.dir / "fogbench.db").c_str(), &db) == SQLITE_OK);
  const std::string sql = "UPDATE samples SET wall_time = wall_time - " + std::to_string(away_wall_s) +
                          " WHERE run_id = " + std::to_string(run);
  REQUIRE(sqlite3_exec(db, sql.c_str(), nullptr, nullptr, nullptr) == SQLITE_OK);
  sqlite3_close(db);
  return run;
}

// Starts the daemon again and waits for the chamber (a resume needs its link up).
void restart(LiveBench& bench, LineClient*& out, std::unique_ptr<LineClient>& keep) {
  bench.start_daemon();
  keep = std::make_unique<LineClient>(bench.socket());
  REQUIRE(keep->ok());
  out = keep.get();
  auto s = bench.wait_status(*out, [](const json& r) { return r["chamber"]["link"] == "up"; }, 30s);
  REQUIRE(s["result"]["chamber"]["link"] == "up");
}

std::int64_t stored(const std::filesystem::path& db_path, std::int64_t run, int unit) {
  storage::OpenOptions ro;
  ro.read_only = true;
  auto store = storage::Store::open(db_path, ro);
  if (!store) return -1;
  auto n = store->count_samples(run, unit);
  return n ? *n : -1;
}

struct Gaps {
  std::size_t rows = 0;                   // rows stored for the unit
  bool contiguous = true;                 // t_s == 0, 1, 2, ... every row
  std::vector<std::pair<double, double>> runs;  // [first, last] t_s of each stretch flagged link_gap
};

Gaps gaps_of(const std::filesystem::path& db_path, std::int64_t run, int unit) {
  storage::OpenOptions ro;
  ro.read_only = true;
  auto store = storage::Store::open(db_path, ro);
  REQUIRE(store.has_value());
  Gaps g;
  bool in_gap = false;
  for (std::int64_t off = 0;; off += 50000) {
    auto page = store->get_samples(run, unit, off, 50000);
    REQUIRE(page.has_value());
    for (const auto& r : *page) {
      if (r.t_s != static_cast<double>(g.rows)) g.contiguous = false;
      ++g.rows;
      const bool gap = (r.flags & model::flag::link_gap) != 0;
      if (gap && !in_gap) g.runs.push_back({r.t_s, r.t_s});
      if (gap) g.runs.back().second = r.t_s;
      in_gap = gap;
    }
    if (page->size() < 50000) break;
  }
  return g;
}

std::vector<json> resume_events(LineClient& c, std::int64_t run) {
  std::vector<json> out;
  auto g = c.call({{"cmd", "run.get"}, {"run_id", run}});
  for (const auto& e : g["result"]["events"])
    if (e["kind"] == "fault" && e["detail"].value("resumed", false)) out.push_back(e["detail"]);
  return out;
}

}  // namespace

TEST_CASE("e2e resume gap: a 30000-second gap is written off the loop, status answers while it is, the time line has it once") {
  require_sim();
  LiveBench bench(50.0);
  const auto run = run_then_kill(bench, 600.0);  // 600 s of wall time at time scale 50: 30,000 s
  const auto killed_at = SteadyClock::now();
  LineClient* c = nullptr;
  std::unique_ptr<LineClient> keep;
  restart(bench, c, keep);
  const auto before = stored(bench.dir / "fogbench.db", run, 0);
  REQUIRE(before > 30);

  const auto t0 = SteadyClock::now();
  auto resumed = c->call({{"cmd", "run.resume"}, {"run_id", run}});
  const double resume_s = std::chrono::duration<double>(SteadyClock::now() - t0).count();
  const double since_kill_s = std::chrono::duration<double>(SteadyClock::now() - killed_at).count();
  REQUIRE(code_of(resumed) == "ok");
  CHECK(resume_s < 2.0);  // the gap is not written before the answer

  // `status` through the write: every answer prompt, until the gap is stored and the run runs.
  double slowest_s = 0.0;
  bool seen_pending = false, done = false;
  const auto deadline = SteadyClock::now() + 120s;
  while (!done && SteadyClock::now() < deadline) {
    const auto a = SteadyClock::now();
    auto s = c->call({{"cmd", "status"}}, 10s);
    slowest_s = std::max(slowest_s, std::chrono::duration<double>(SteadyClock::now() - a).count());
    REQUIRE(code_of(s) == "ok");
    const auto& r = s["result"]["run"];
    REQUIRE(r.is_object());
    if (r["samples_pending"].get<int>() > 0) seen_pending = true;
    done = r["state"] == "running" && stored(bench.dir / "fogbench.db", run, 0) > before + 30000;
    std::this_thread::sleep_for(20ms);
  }
  REQUIRE(done);
  INFO("slowest status " << slowest_s << " s; a status saw the gap pending: " << seen_pending);
  CHECK(slowest_s < 2.0);
  REQUIRE(code_of(c->call({{"cmd", "run.abort"}, {"reason", "gap checked"}})) == "ok");

  for (int unit : {0, 1}) {
    const auto g = gaps_of(bench.dir / "fogbench.db", run, unit);
    INFO("unit " << unit);
    CHECK(g.contiguous);
    REQUIRE(g.runs.size() == 1);  // one gap, once
    CHECK(g.runs[0].first == static_cast<double>(before));
    const double len = g.runs[0].second - g.runs[0].first + 1;
    CHECK(len >= 30000.0);
    CHECK(len <= 30000.0 + (since_kill_s + 2.0) * 50.0);
  }
  auto ev = resume_events(*c, run);
  REQUIRE(ev.size() == 1);
  CHECK(ev[0]["gap_from_s"] == static_cast<double>(before));
  CHECK(ev[0]["gap_to_s"].get<double>() == ev[0]["gap_from_s"].get<double>() + ev[0]["gap_s"].get<double>());
}

TEST_CASE("e2e resume gap: SIGKILL while the gap is written, the next resume completes it: the gap once") {
  require_sim();
  LiveBench bench(50.0);
  // 6,000 s of wall time at time scale 50: a 300,000-second gap, hundreds of slices.
  const auto run = run_then_kill(bench, 6000.0);
  const auto killed_at = SteadyClock::now();
  LineClient* c = nullptr;
  std::unique_ptr<LineClient> keep;
  restart(bench, c, keep);
  const auto db = bench.dir / "fogbench.db";
  const auto before = stored(db, run, 0);
  REQUIRE(before > 30);
  REQUIRE(code_of(c->call({{"cmd", "run.resume"}, {"run_id", run}})) == "ok");
  // Killed once part of the gap is stored.
  const auto deadline = SteadyClock::now() + 60s;
  std::int64_t part = before;
  while (part == before && SteadyClock::now() < deadline) {
    std::this_thread::sleep_for(2ms);
    part = stored(db, run, 0);
  }
  bench.daemon->kill_now();
  keep.reset();
  const auto partial = stored(db, run, 0) - before;
  INFO("gap seconds stored before the kill: " << partial);
  REQUIRE(partial > 0);
  const bool mid_write = partial < 300000;
  if (!mid_write) WARN("the gap was stored whole before the kill: the completion is not exercised");

  restart(bench, c, keep);
  REQUIRE(code_of(c->call({{"cmd", "run.resume"}, {"run_id", run}})) == "ok");
  const double since_kill_s = std::chrono::duration<double>(SteadyClock::now() - killed_at).count();
  auto s = bench.wait_status(*c, [](const json& r) {
    return r["run"].is_object() && r["run"]["state"] == "running" && r["run"]["samples_pending"] == 0;
  }, 120s);
  REQUIRE(s["result"]["run"]["state"] == "running");
  REQUIRE(code_of(c->call({{"cmd", "run.abort"}, {"reason", "gap checked"}})) == "ok");

  auto ev = resume_events(*c, run);
  REQUIRE(ev.size() == 2);
  if (mid_write) {
    // The second resume completed the first's gap and said so.
    CHECK(ev[1]["gap_stored_before_s"] == static_cast<double>(partial));
    CHECK(ev[1]["gap_started_s"] == static_cast<double>(before));
    CHECK(ev[1]["gap_from_s"] == static_cast<double>(before + partial));
  }
  for (int unit : {0, 1}) {
    const auto g = gaps_of(db, run, unit);
    INFO("unit " << unit);
    CHECK(g.contiguous);
    REQUIRE(g.runs.size() == 1);
    CHECK(g.runs[0].first == static_cast<double>(before));
    CHECK(g.runs[0].second + 1 == ev[1]["gap_to_s"].get<double>());
    // The time away, counted once: not the first slices again on top of it.
    const double len = g.runs[0].second - g.runs[0].first + 1;
    CHECK(len >= 300000.0);
    CHECK(len <= 300000.0 + (since_kill_s + 2.0) * 50.0);
  }
}

TEST_CASE("e2e resume gap: the replay of 300000 stored seconds runs off the loop, status answers while it runs") {
  require_sim();
  LiveBench bench(50.0);
  // A run with 300,000 seconds stored: a first resume's gap (6,000 s of wall time at time scale
  // 50), stored whole, then the daemon killed again.
  const auto run = run_then_kill(bench, 6000.0);
  LineClient* c = nullptr;
  std::unique_ptr<LineClient> keep;
  restart(bench, c, keep);
  REQUIRE(code_of(c->call({{"cmd", "run.resume"}, {"run_id", run}})) == "ok");
  auto s = bench.wait_status(*c, [](const json& r) {
    return r["run"].is_object() && r["run"]["state"] == "running" && r["run"]["samples_pending"] == 0;
  }, 120s);
  REQUIRE(s["result"]["run"]["state"] == "running");
  bench.daemon->kill_now();
  keep.reset();
  REQUIRE(stored(bench.dir / "fogbench.db", run, 0) > 300000);

  restart(bench, c, keep);
  LineClient other(bench.socket());
  REQUIRE(other.ok());
  REQUIRE(other.line());  // its hello
  // run.resume sent, not waited for: the other client asks `status` until its answer comes.
  REQUIRE(c->send_raw(json{{"id", 900}, {"cmd", "run.resume"}, {"run_id", run}}.dump() + "\n"));
  const auto t0 = SteadyClock::now();
  double slowest_s = 0.0;
  int answered = 0;
  bool seen_resuming = false;
  std::optional<json> resumed;
  while (!resumed && SteadyClock::now() - t0 < 60s) {
    const auto a = SteadyClock::now();
    auto st = other.call({{"cmd", "status"}}, 10s);
    slowest_s = std::max(slowest_s, std::chrono::duration<double>(SteadyClock::now() - a).count());
    REQUIRE(code_of(st) == "ok");
    ++answered;
    if (st["result"].value("resuming_run_id", json(nullptr)) == json(run)) seen_resuming = true;
    if (auto l = c->line(20ms)) {  // (under 1 ms, line() does not read)
      auto j = json::parse(*l, nullptr, false);
      if (j.is_object() && j.value("type", "") == "reply" && j["id"] == 900) resumed = j;
    }
  }
  REQUIRE(resumed.has_value());
  CHECK(code_of(*resumed) == "ok");
  const double resume_s = std::chrono::duration<double>(SteadyClock::now() - t0).count();
  INFO("run.resume answered after " << resume_s << " s; " << answered << " status meanwhile, the slowest "
                                    << slowest_s << " s");
  // The replay took the worker 0.95 s here (on the loop before: status waited as long). While it
  // runs, status answers and says which run is being resumed.
  CHECK(seen_resuming);
  CHECK(slowest_s < 0.5);
  // Nothing else starts meanwhile, and the run is taken up once, its gap after the stored seconds.
  REQUIRE(code_of(c->call({{"cmd", "run.abort"}, {"reason", "replay checked"}})) == "ok");
  auto ev = resume_events(*c, run);
  REQUIRE(ev.size() == 2);
  CHECK(ev[1]["gap_from_s"].get<double>() >= 300000.0);
}

TEST_CASE("e2e resume gap: an 850000-second gap of 2 units is written whole, the run not aborted as stalled") {
  require_sim();
  LiveBench bench(50.0);
  // 17,000 s of wall time at time scale 50: 850,000 s, 1.7 million rows, more than the 30 s of
  // the writer's stall rule to store (before: the run aborted "storage stalled" after 30 s).
  const auto run = run_then_kill(bench, 17000.0);
  LineClient* c = nullptr;
  std::unique_ptr<LineClient> keep;
  restart(bench, c, keep);
  const auto before = stored(bench.dir / "fogbench.db", run, 0);
  REQUIRE(code_of(c->call({{"cmd", "run.resume"}, {"run_id", run}})) == "ok");
  auto s = bench.wait_status(*c, [](const json& r) {
    return !r["run"].is_object() || (r["run"]["state"] == "running" && r["run"]["samples_pending"] == 0);
  }, 300s);
  INFO(s.dump());
  REQUIRE(s["result"]["run"].is_object());
  REQUIRE(s["result"]["run"]["state"] == "running");
  REQUIRE(code_of(c->call({{"cmd", "run.abort"}, {"reason", "gap checked"}})) == "ok");
  for (int unit : {0, 1}) {
    const auto g = gaps_of(bench.dir / "fogbench.db", run, unit);
    INFO("unit " << unit);
    CHECK(g.contiguous);
    REQUIRE(g.runs.size() == 1);
    CHECK(g.runs[0].first == static_cast<double>(before));
    CHECK(g.runs[0].second - g.runs[0].first + 1 >= 850000.0);
  }
}
