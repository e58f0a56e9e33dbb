// A stop that the plant cannot hold (issue 27, point 3): fogbenchd sends a big completed run to a
// real PostgreSQL (tests/plant/pg_server.hpp), the test freezes the server's backend (SIGSTOP)
// during the samples' COPY; `status.plant` says the link is stalled; SIGTERM ends the daemon with
// status 0 well within systemd's TimeoutStopSec (the stop's budget, docs/reliability.md), its log
// naming the abandoned transaction; nothing of the run is committed in the plant; after the
// backend is let go and the daemon restarted, the run reaches the plant once, every sample once.
// Exits 77 (SKIPPED) where the server's binaries are missing.
#include "live_bench.hpp"

#include <csignal>

#include "../plant/pg_server.hpp"
#include "fogbench/storage/runs.hpp"
#include "fogbench/storage/samples.hpp"
#include "fogbench/storage/store.hpp"

using namespace fogbench;
using namespace fogbench::daemon::test;
using namespace fogbench::daemon::test::live;
using nlohmann::json;
using namespace std::chrono_literals;

namespace {

// A completed run of one unit with `n` samples, written straight into a new store: the daemon
// queues it for the plant at its start (a completed run never queued).
std::int64_t big_completed_run(const std::filesystem::path& path, int n) {
  auto s = storage::Store::open(path);
  REQUIRE(s);
  storage::NewRun nr;
  nr.profile_name = "p";
  nr.unit_serials = {"FOG-0001"};
  auto id = s->create_run(nr);
  REQUIRE(id);
  REQUIRE(s->set_run_state(*id, storage::RunState::running, "go"));
  std::vector<storage::SampleRow> rows;
  for (int i = 0; i < n; ++i) {
    storage::SampleRow r;
    r.t_s = i;
    r.gyro_dph = 0.001 * i;
    r.t1_c = 20 + 1e-5 * i;
    r.t2_c = 20 - 1e-5 * i;
    rows.push_back(r);
    if (rows.size() == 50000) {
      REQUIRE(s->append_samples(*id, rows));
      rows.clear();
    }
  }
  if (!rows.empty()) REQUIRE(s->append_samples(*id, rows));
  REQUIRE(s->set_run_state(*id, storage::RunState::completed, "done"));
  return *id;
}

// Lets a frozen backend go whatever happens, so the server can stop at the end.
struct Thaw {
  pid_t pid = 0;
  void now() {
    if (pid > 0) ::kill(pid, SIGCONT);
    pid = 0;
  }
  ~Thaw() { now(); }
};

std::string slurp(const std::filesystem::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

}  // namespace

TEST_CASE("e2e plant stop: SIGTERM with the plant's backend frozen mid-COPY exits within the budget, the run is sent once after a restart") {
  fogbench::test::PgServer pg;  // first: exits 77 (SKIPPED) without the server's binaries
  require_sim();
  char tmpl[] = "/tmp/fogbench-plant-stop-XXXXXX";
  const std::filesystem::path store_dir = ::mkdtemp(tmpl);
  const auto store_path = store_dir / "bench.db";
  // 400,000 samples: their COPY lasts long enough (about a second or more) to be caught active.
  constexpr int kSamples = 400000;
  const auto run = big_completed_run(store_path, kSamples);
  const std::string rid = std::to_string(run);

  LiveBench bench(50.0,
                  {{"storage", {{"path", store_path.string()}}},
                   {"plant", {{"conninfo", pg.conninfo()}, {"bench_id", "stop-bench"}, {"poll_s", 0.1},
                              {"retry_max_s", 1}, {"stall_s", 2}}}});
  INFO("test dir " << bench.dir << ", store " << store_path);

  // The backend running the samples' COPY, frozen.
  Thaw thaw;
  const auto find_deadline = SteadyClock::now() + 120s;
  std::string pid;
  while (SteadyClock::now() < find_deadline && pid.empty()) {
    pid = pg.psql("SELECT pid FROM pg_stat_activity WHERE state = 'active' AND query LIKE 'COPY fogbench.samples%'");
    if (pid.empty()) std::this_thread::sleep_for(10ms);
  }
  REQUIRE_FALSE(pid.empty());
  thaw.pid = static_cast<pid_t>(std::stoi(pid));
  REQUIRE(::kill(thaw.pid, SIGSTOP) == 0);

  // status.plant: stalled, on that run (stall_s 2).
  LineClient c(bench.socket());
  REQUIRE(c.ok());
  json s = bench.wait_status(c, [](const json& r) { return r.contains("plant") && r["plant"].value("stalled", false); },
                             60s);
  INFO(s.dump());
  REQUIRE(s["result"]["plant"]["stalled"] == true);
  CHECK(s["result"]["plant"]["link"] == "stalled");
  CHECK(s["result"]["plant"]["sending_run_id"] == run);
  CHECK(s["result"]["plant"]["link_quiet_s"].get<double>() >= 2.0);
  CHECK(s["result"]["plant"]["outbox_depth"] == 1);

  // SIGTERM: out with status 0 well within TimeoutStopSec=20 (the budget is 15 s; the plant's
  // share 3 s, then 2 s at most to end once its socket is cut).
  const auto t0 = SteadyClock::now();
  const int rc = bench.daemon->stop(30s);
  const double took_s = std::chrono::duration<double>(SteadyClock::now() - t0).count();
  const std::string log = slurp(bench.dir / "fogbenchd.log");
  std::ofstream(bench.dir / "fogbenchd-first.log") << log;  // the restart below truncates the log
  INFO("exit " << rc << " after " << took_s << " s; log:\n" << log);
  CHECK(rc == 0);
  CHECK(took_s < 10.0);
  CHECK(log.find("abandoned the transaction sending run " + rid) != std::string::npos);
  CHECK(log.find("stopped in ") != std::string::npos);

  // Nothing of the run committed in the plant, frozen or let go.
  thaw.now();
  CHECK(pg.psql("SELECT count(*) FROM fogbench.runs WHERE bench_id = 'stop-bench'") == "0");
  // The backend sees its client gone and rolls back (it holds the run's rows until then).
  const auto gone_deadline = SteadyClock::now() + 60s;
  while (SteadyClock::now() < gone_deadline &&
         !pg.psql("SELECT pid FROM pg_stat_activity WHERE pid = " + pid).empty())
    std::this_thread::sleep_for(100ms);
  CHECK(pg.psql("SELECT pid FROM pg_stat_activity WHERE pid = " + pid).empty());

  // The next start sends it: once, every sample once.
  bench.start_daemon();
  LineClient c2(bench.socket());
  REQUIRE(c2.ok());
  s = bench.wait_status(
      c2, [](const json& r) { return r.contains("plant") && r["plant"].value("outbox_depth", -1) == 0; }, 300s);
  INFO(s.dump());
  REQUIRE(s["result"]["plant"]["outbox_depth"] == 0);
  CHECK(s["result"]["plant"]["link"] == "idle");
  CHECK(s["result"]["plant"]["stalled"] == false);
  CHECK(pg.psql("SELECT count(*) FROM fogbench.runs WHERE bench_id = 'stop-bench'") == "1");
  CHECK(pg.psql("SELECT count(*) FROM fogbench.samples WHERE bench_id = 'stop-bench' AND run_id = " + rid) ==
        std::to_string(kSamples));
  CHECK(pg.psql("SELECT count(DISTINCT t_s) FROM fogbench.samples WHERE bench_id = 'stop-bench' AND run_id = " + rid) ==
        std::to_string(kSamples));
  bench.daemon->stop(30s);
  std::error_code ec;
  if (!std::getenv("FOGBENCH_KEEP_TEST_DIRS")) std::filesystem::remove_all(store_dir, ec);
}
