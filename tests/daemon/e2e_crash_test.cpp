// fogbenchd killed with SIGKILL in the middle of a run and started again on the same store:
// every second stored up to the kill, the store intact, the run interrupted with its reason,
// the chamber back at the safe setpoint, and the interrupted run still usable (export, fit)
// and resumable (run.resume).
#include "live_bench.hpp"

#include <sqlite3.h>

#include <fstream>
#include <sstream>

#include "fogbench/storage/samples.hpp"
#include "fogbench/storage/store.hpp"

using namespace fogbench;
using namespace fogbench::daemon::test;
using namespace fogbench::daemon::test::live;
using nlohmann::json;
using namespace std::chrono_literals;

TEST_CASE("e2e crash: SIGKILL mid-run loses no stored second, the restart marks the run interrupted and goes safe") {
  require_sim();
  LiveBench bench(50.0);
  std::int64_t run = 0;
  double elapsed_before_kill_s = 0;
  double samples_pending = 0;  // seconds handed to the writer thread and not yet committed
  {
    LineClient c(bench.socket());
    REQUIRE(c.ok());
    run = bench.start_run(c, "short", {"SIM-0001", "SIM-0002"});
    // Past the ramp to 25 degC (step 2) into the hold after it, so the run has something to
    // fit, and with the controller's setpoint away from the safe 20 degC. The seconds are
    // committed by the writer thread a little after the loop hands them over (a busy host: 174
    // of 900 s at time scale 50 still queued, CI 2026-11-28): wait until it has caught up, so
    // the stored seconds reach the hold too.
    auto s = bench.wait_status(c, [](const json& r) {
      return r["run"].is_object() && r["run"]["step"].get<int>() >= 3 && r["chamber"]["setpoint_c"].is_number() &&
             r["chamber"]["setpoint_c"].get<double>() > 21.0 && r["run"].value("samples_pending", 0) <= 1;
    }, 120s);
    REQUIRE(s["result"]["run"]["step"].get<int>() >= 3);
    elapsed_before_kill_s = s["result"]["run"]["elapsed_s"].get<double>();
    samples_pending = s["result"]["run"].value("samples_pending", 0.0);
  }
  bench.daemon->kill_now();

  {
    // Straight from the file, before anything touches it again.
    storage::OpenOptions ro;
    ro.read_only = true;
    auto store = storage::Store::open(bench.dir / "fogbench.db", ro);
    REQUIRE(store.has_value());
    auto ic = store->integrity_check();
    REQUIRE(ic.has_value());
    CHECK(ic->empty());  // no problem found
    for (int unit : {0, 1}) {
      auto n = store->count_samples(run, unit);
      REQUIRE(n.has_value());
      // Every second up to the last one stored is there: the seconds are 0 .. n - 1, and every
      // second `status` reported before the kill was stored, but those it said were still
      // queued for the writer (a SIGKILL loses the queue, never a committed second).
      INFO("elapsed " << elapsed_before_kill_s << " s, " << samples_pending << " still queued");
      CHECK(static_cast<double>(*n) >= elapsed_before_kill_s + 1 - samples_pending);
      auto last = store->get_samples(run, unit, *n - 1, 1);
      REQUIRE(last.has_value());
      REQUIRE(last->size() == 1);
      CHECK(last->at(0).t_s == static_cast<double>(*n - 1));
    }
  }

  bench.start_daemon();
  LineClient c(bench.socket());
  REQUIRE(c.ok());
  auto g = c.call({{"cmd", "run.get"}, {"run_id", run}});
  REQUIRE(code_of(g) == "ok");
  CHECK(g["result"]["run"]["state"] == "interrupted");
  CHECK_THAT(g["result"]["run"]["reason"].get<std::string>(), Catch::Contains("daemon restarted"));
  CHECK(g["result"]["samples"][0] == g["result"]["samples"][1]);
  auto s = bench.wait_status(c, [](const json& r) { return r["chamber"]["setpoint_c"] == 20.0; }, 30s);
  CHECK(s["result"]["chamber"]["setpoint_c"] == 20.0);
  CHECK(s["result"]["run"].is_null());

  // The interrupted run is still data: its samples page out and it fits.
  auto page = c.call({{"cmd", "run.samples"}, {"run_id", run}, {"unit", 0}, {"limit", 10000}});
  REQUIRE(code_of(page) == "ok");
  CHECK(page["result"]["total"] == g["result"]["samples"][0]);
  auto fit = c.call({{"cmd", "model.fit"}, {"run_id", run}, {"unit", 0}});
  INFO(fit.dump());
  CHECK(code_of(fit) == "ok");

  // Or the operator takes it up again: the profile goes on, the time away is stored flagged.
  const auto before = g["result"]["samples"][0].get<std::int64_t>();
  auto resumed = c.call({{"cmd", "run.resume"}, {"run_id", run}});
  REQUIRE(code_of(resumed) == "ok");
  auto on = bench.wait_status(c, [](const json& r) {
    return r["run"].is_object() && r["run"]["state"] == "running";
  }, 60s);
  REQUIRE(on["result"]["run"].is_object());
  CHECK(on["result"]["run"]["id"] == run);
  CHECK(on["result"]["run"]["step"].get<int>() >= 3);  // where it stood, not from the start
  REQUIRE(code_of(c.call({{"cmd", "run.abort"}, {"reason", "resumed enough"}})) == "ok");
  auto after = c.call({{"cmd", "run.get"}, {"run_id", run}});
  bool resume_event = false;
  for (const auto& e : after["result"]["events"])
    if (e["kind"] == "fault" && e["detail"].value("resumed", false)) resume_event = true;
  CHECK(resume_event);
  auto all = c.call({{"cmd", "run.samples"}, {"run_id", run}, {"unit", 0}, {"limit", 10000}});
  REQUIRE(code_of(all) == "ok");
  const auto& rows = all["result"]["samples"];
  CHECK(static_cast<std::int64_t>(rows.size()) > before);
  // Every second of the run clock, the time away included (flagged link_gap + missing).
  for (std::size_t i = 0; i < rows.size(); ++i) CHECK(rows[i]["t_s"].get<double>() == static_cast<double>(i));
  std::size_t gap_rows = 0;
  for (std::size_t i = static_cast<std::size_t>(before); i < rows.size() && (rows[i]["flags"].get<int>() & 8); ++i) {
    CHECK(rows[i]["chamber_c"].is_null());
    ++gap_rows;
  }
  REQUIRE(gap_rows > 0);

  // fogctl's export keeps the time away empty (docs/csv.md): no reading is repeated across it.
  require_fogctl();
  const auto csv_path = bench.dir / "resumed.csv";
  const std::string cmd = "'" + (kBin / "fogctl").string() + "' run export " + std::to_string(run) + " --unit 0 -o '" +
                          csv_path.string() + "' --socket '" + bench.socket().string() + "' 2>/dev/null";
  REQUIRE(std::system(cmd.c_str()) == 0);
  std::ifstream in(csv_path);
  std::string line;
  std::vector<std::string> header;
  std::size_t empty_chamber = 0, t_col = 0, chamber_col = 0;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::vector<std::string> cells;
    std::stringstream ss(line);
    for (std::string cell; std::getline(ss, cell, ',');) cells.push_back(cell);
    if (!line.empty() && line.back() == ',') cells.emplace_back();
    if (header.empty()) {
      header = cells;
      for (std::size_t k = 0; k < header.size(); ++k) {
        if (header[k] == "time_s") t_col = k;
        if (header[k] == "chamber_c") chamber_col = k;
      }
      REQUIRE(header.at(chamber_col) == "chamber_c");
      continue;
    }
    REQUIRE(cells.size() == header.size());
    const double t = std::stod(cells[t_col]);
    if (t >= static_cast<double>(before) && t < static_cast<double>(before + static_cast<std::int64_t>(gap_rows))) {
      INFO("t = " << t << ": " << line);
      CHECK(cells[chamber_col].empty());
      if (cells[chamber_col].empty()) ++empty_chamber;
    }
  }
  CHECK(empty_chamber == gap_rows);
}

TEST_CASE("e2e crash: a store locked at restart does not keep fogbenchd from starting and going safe, the marks follow") {
  require_sim();
  LiveBench bench(50.0, {{"safe_setpoint_c", 15}});
  std::int64_t run = 0;
  {
    LineClient c(bench.socket());
    REQUIRE(c.ok());
    run = bench.start_run(c, "short", {"SIM-0001"});
    REQUIRE(bench.wait_status(c, [](const json& r) {
      return r["run"].is_object() && r["chamber"]["setpoint_c"] == 20.0;
    }, 60s)["result"]["run"].is_object());
  }
  bench.daemon->kill_now();
  // Someone holds the store's write lock (a sqlite3 shell, a backup) while the daemon restarts.
  sqlite3* other = nullptr;
  REQUIRE(sqlite3_open((bench.dir / "fogbench.db").c_str(), &other) == SQLITE_OK);
  REQUIRE(sqlite3_exec(other, "BEGIN IMMEDIATE", nullptr, nullptr, nullptr) == SQLITE_OK);
  bench.start_daemon();  // it waits out its busy timeout (5 s) on the marks, then goes on
  LineClient c(bench.socket());
  REQUIRE(c.ok());
  auto s = bench.wait_status(c, [](const json& r) { return r["chamber"]["setpoint_c"] == 15.0; }, 30s);
  CHECK(s["result"]["chamber"]["setpoint_c"] == 15.0);
  REQUIRE(s["result"]["recovery"].is_object());
  CHECK_THAT(s["result"]["recovery"]["error"].get<std::string>(), Catch::Contains("busy"));
  auto refused = c.call({{"cmd", "run.start"}, {"profile", "short"}, {"units", {"SIM-0001"}}});
  CHECK(code_of(refused) == "internal");
  CHECK_THAT(refused.dump(), Catch::Contains("not yet marked interrupted"));
  CHECK(c.call({{"cmd", "run.get"}, {"run_id", run}})["result"]["run"]["state"] == "running");

  REQUIRE(sqlite3_exec(other, "ROLLBACK", nullptr, nullptr, nullptr) == SQLITE_OK);
  sqlite3_close(other);
  // Retried every 10 s of wall time.
  auto marked = bench.wait_status(c, [](const json& r) { return r["recovery"].is_null(); }, 40s);
  CHECK(marked["result"]["recovery"].is_null());
  auto g = c.call({{"cmd", "run.get"}, {"run_id", run}});
  CHECK(g["result"]["run"]["state"] == "interrupted");
  CHECK_THAT(g["result"]["run"]["reason"].get<std::string>(), Catch::Contains("daemon restarted"));
  CHECK(code_of(c.call({{"cmd", "run.resume"}, {"run_id", run}})) == "ok");
  CHECK(code_of(c.call({{"cmd", "run.abort"}})) == "ok");
}
