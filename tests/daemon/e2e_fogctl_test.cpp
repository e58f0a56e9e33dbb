// fogctl, the built executable, against the real fogbenchd on the live mock bench: the data
// quality of a run in `status` and `run get` (table and --json), TCP with --connect and a
// token (--token or $FOGBENCH_TOKEN), `run resume` of a run a crash interrupted, and a run end
// the store has not taken yet.
#include "live_bench.hpp"

#include <sqlite3.h>
#include <sys/wait.h>

using namespace fogbench::daemon::test;
using namespace fogbench::daemon::test::live;
using nlohmann::json;
using namespace std::chrono_literals;

namespace {

struct Out {
  int code = -1;
  std::string out, err;
};

std::string slurp(const std::filesystem::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// Runs fogctl with `args` (shell words, quoted by the caller) and `env` (VAR=value ...) in the
// bench's directory; its exit code, stdout and stderr.
Out fogctl(const LiveBench& bench, const std::string& args, const std::string& env = "") {
  const auto out = bench.dir / "fogctl.out", err = bench.dir / "fogctl.err";
  // FOGBENCH_TOKEN from the test's own environment must not leak in.
  const std::string cmd = "cd '" + bench.dir.string() + "' && env -u FOGBENCH_TOKEN " + env + " '" +
                          (kBin / "fogctl").string() + "' " + args + " >'" + out.string() + "' 2>'" + err.string() + "'";
  const int st = std::system(cmd.c_str());
  Out o;
  o.code = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
  o.out = slurp(out);
  o.err = slurp(err);
  return o;
}

std::string sock(const LiveBench& bench) { return "--socket '" + bench.socket().string() + "'"; }


// The table line that starts with `unit` and names `serial`, split into words.
std::vector<std::string> row_of(const std::string& text, const std::string& serial) {
  std::istringstream lines(text);
  std::string l;
  while (std::getline(lines, l)) {
    std::istringstream w(l);
    std::vector<std::string> words;
    for (std::string x; w >> x;) words.push_back(x);
    if (words.size() > 2 && words[1] == serial) return words;
  }
  return {};
}

}  // namespace

TEST_CASE("e2e fogctl: status and run get show each unit's frames lost, frames corrupt and samples flagged") {
  require_sim();
  require_fogctl();
  LiveBench bench(20.0);
  auto start = fogctl(bench, "run start " + sock(bench) + " --profile short --unit SIM-0001 --unit SIM-0002 --json");
  INFO(start.err);
  REQUIRE(start.code == 0);
  const auto run = json::parse(start.out)["run_id"].get<std::int64_t>();
  REQUIRE(bench.sim_command({{"cmd", "fault"}, {"name", "lose_frames"}, {"unit", 0}, {"fraction", 0.2}})["ok"] == true);
  REQUIRE(bench.sim_command({{"cmd", "fault"}, {"name", "corrupt_frames"}, {"unit", 0}, {"fraction", 0.1}})["ok"] == true);
  LineClient c(bench.socket());
  REQUIRE(c.ok());
  REQUIRE(bench.wait_status(c, [](const json& r) {
    return r["run"].is_object() && r["run"]["quality"][0]["frames_lost"].get<int>() > 0 &&
           r["run"]["quality"][0]["frames_corrupt"].get<int>() > 0;
  }, 60s)["result"]["run"].is_object());

  auto sj = fogctl(bench, "status --json " + sock(bench));
  REQUIRE(sj.code == 0);
  const json s = json::parse(sj.out);
  const json& q = s["run"]["quality"];
  REQUIRE(q.size() == 2);
  CHECK(q[0]["frames_lost"].get<int>() > 0);
  CHECK(q[0]["frames_corrupt"].get<int>() > 0);
  CHECK(q[1]["frames_lost"] == 0);
  auto st = fogctl(bench, "status " + sock(bench));
  REQUIRE(st.code == 0);
  CHECK(st.out.find("frames_lost") != std::string::npos);
  CHECK(st.out.find("samples_flagged") != std::string::npos);
  // Columns: unit serial frames_lost frames_corrupt samples_flagged; unit 0 lost some, unit 1 none.
  auto r0 = row_of(st.out.substr(st.out.find("data quality")), "SIM-0001");
  auto r1 = row_of(st.out.substr(st.out.find("data quality")), "SIM-0002");
  REQUIRE(r0.size() == 5);
  REQUIRE(r1.size() == 5);
  CHECK(std::stoll(r0[2]) > 0);
  CHECK(std::stoll(r0[3]) > 0);
  CHECK(r1[2] == "0");
  CHECK(r1[3] == "0");

  REQUIRE(fogctl(bench, "run abort " + sock(bench) + " --reason enough").code == 0);
  auto gj = fogctl(bench, "run get " + std::to_string(run) + " --json " + sock(bench));
  REQUIRE(gj.code == 0);
  const json g = json::parse(gj.out);
  REQUIRE(g["quality"].is_array());
  const auto lost = g["quality"][0]["frames_lost"].get<std::int64_t>();
  const auto corrupt = g["quality"][0]["frames_corrupt"].get<std::int64_t>();
  const auto flagged = g["quality"][0]["samples_flagged"].get<std::int64_t>();
  CHECK(lost >= q[0]["frames_lost"].get<std::int64_t>());
  CHECK(flagged > 0);
  auto gt = fogctl(bench, "run get " + std::to_string(run) + " " + sock(bench));
  REQUIRE(gt.code == 0);
  // Columns: unit serial samples frames_lost frames_corrupt samples_flagged.
  auto g0 = row_of(gt.out, "SIM-0001");
  REQUIRE(g0.size() == 6);
  CHECK(g0[2] == std::to_string(g["samples"][0].get<std::int64_t>()));
  CHECK(g0[3] == std::to_string(lost));
  CHECK(g0[4] == std::to_string(corrupt));
  CHECK(g0[5] == std::to_string(flagged));
}

TEST_CASE("e2e fogctl: --connect reaches fogbenchd over TCP, control needs --token or FOGBENCH_TOKEN") {
  require_sim();
  require_fogctl();
  const std::string token = "fogctl-e2e-token-0123456789";
  const auto port = free_port();
  LiveBench bench(20.0, {{"socket", {{"tcp", {{"port", port}, {"token", token}}}}}});
  const std::string tcp = "--connect 127.0.0.1:" + std::to_string(port);
  // --socket points nowhere: everything here must go over TCP.
  const std::string nowhere = "--socket /nonexistent/fogbenchd.sock ";

  auto s = fogctl(bench, "status --json " + nowhere + tcp);
  INFO(s.err);
  REQUIRE(s.code == 0);
  CHECK(json::parse(s.out)["simulated"] == true);
  CHECK(fogctl(bench, "run list " + nowhere + tcp).code == 0);

  auto denied = fogctl(bench, "run start " + nowhere + tcp + " --profile short --unit SIM-0001");
  CHECK(denied.code == 2);
  CHECK_THAT(denied.err, Catch::Contains("forbidden"));
  auto wrong = fogctl(bench, "run start " + nowhere + tcp + " --token not-the-token --profile short --unit SIM-0001");
  CHECK(wrong.code == 2);
  CHECK_THAT(wrong.err, Catch::Contains("forbidden"));
  LineClient c(bench.socket());
  CHECK(c.call({{"cmd", "status"}})["result"]["run"].is_null());  // nothing started

  auto ok = fogctl(bench, "run start --json " + nowhere + tcp + " --profile short --unit SIM-0001",
                   "FOGBENCH_TOKEN=" + token);
  INFO(ok.err);
  REQUIRE(ok.code == 0);
  const auto run = json::parse(ok.out)["run_id"].get<std::int64_t>();
  CHECK(c.call({{"cmd", "status"}})["result"]["run"]["id"] == run);
  // A few seconds stored before the abort, for fit --run below.
  bench.wait_status(c, [](const json& r) { return r["run"].is_object() && r["run"]["elapsed_s"].get<double>() >= 5; }, 60s);
  auto abort = fogctl(bench, "run abort " + nowhere + tcp + " --token " + token + " --reason tcp");
  INFO(abort.err);
  CHECK(abort.code == 0);
  auto g = c.call({{"cmd", "run.get"}, {"run_id", run}});
  CHECK(g["result"]["run"]["reason"] == "aborted by operator: tcp");
  // The token is never stored with the command.
  CHECK(g["result"].dump().find(token) == std::string::npos);
  // fit --run fetches the stored run over TCP too (reads need no token). The aborted run is
  // seconds long, so the fit itself refuses it: the refusal is the model's, not a connection's.
  auto fit = fogctl(bench, "fit --run " + std::to_string(run) + " " + nowhere + tcp);
  CHECK(fit.code == 2);
  CHECK_THAT(fit.err, Catch::Contains("run" + std::to_string(run) + "-unit0"));
  CHECK_THAT(fit.err, !Catch::Contains("connect"));

  // Bad endpoints: a clear message naming --connect, exit 2.
  for (const std::string bad : {"127.0.0.1", "127.0.0.1:http", "127.0.0.1:70000", ":7000"}) {
    auto r = fogctl(bench, "status --connect " + bad);
    CHECK(r.code == 2);
    CHECK_THAT(r.err, Catch::Contains("--connect"));
  }
  auto refused = fogctl(bench, "status --connect 127.0.0.1:" + std::to_string(free_port()));
  CHECK(refused.code == 2);
  CHECK_THAT(refused.err, Catch::Contains("cannot connect to fogbenchd at 127.0.0.1:"));
}

TEST_CASE("e2e fogctl: run resume takes up a run a crash interrupted, it refuses what it cannot resume") {
  require_sim();
  require_fogctl();
  LiveBench bench(50.0);
  std::int64_t run = 0;
  {
    LineClient c(bench.socket());
    REQUIRE(c.ok());
    run = bench.start_run(c, "short", {"SIM-0001"});
    REQUIRE(bench.wait_status(c, [](const json& r) {
      return r["run"].is_object() && r["run"]["step"].get<int>() >= 2;
    }, 120s)["result"]["run"].is_object());
  }
  bench.daemon->kill_now();
  bench.start_daemon();
  LineClient c(bench.socket());
  REQUIRE(c.ok());
  REQUIRE(c.call({{"cmd", "run.get"}, {"run_id", run}})["result"]["run"]["state"] == "interrupted");
  // No counts for the part before the crash: they were in the dead daemon's memory.
  auto before = fogctl(bench, "run get " + std::to_string(run) + " --json " + sock(bench));
  REQUIRE(before.code == 0);
  CHECK(json::parse(before.out)["quality"].is_null());

  auto help = fogctl(bench, "run resume --help");
  CHECK(help.code == 0);
  CHECK_THAT(help.out, Catch::Contains("interrupted"));
  auto missing = fogctl(bench, "run resume " + sock(bench));
  CHECK(missing.code == 2);
  auto not_number = fogctl(bench, "run resume abc " + sock(bench));
  CHECK(not_number.code == 2);
  auto unknown = fogctl(bench, "run resume " + std::to_string(run + 100) + " " + sock(bench));
  CHECK(unknown.code == 2);
  CHECK_THAT(unknown.err, Catch::Contains("not_found"));

  auto resumed = fogctl(bench, "run resume " + std::to_string(run) + " " + sock(bench));
  INFO(resumed.err);
  REQUIRE(resumed.code == 0);
  CHECK_THAT(resumed.out, Catch::Contains("run " + std::to_string(run) + " resumes"));
  auto on = bench.wait_status(c, [](const json& r) { return r["run"].is_object() && r["run"]["state"] == "running"; }, 60s);
  REQUIRE(on["result"]["run"].is_object());
  CHECK(on["result"]["run"]["id"] == run);
  CHECK(on["result"]["run"]["step"].get<int>() >= 2);  // where it stood, not from the start
  // Resumed already, and a run is active: refused, exit 2, the daemon's reason shown.
  auto again = fogctl(bench, "run resume " + std::to_string(run) + " " + sock(bench));
  CHECK(again.code == 2);
  CHECK_THAT(again.err, Catch::Contains("busy"));
  REQUIRE(fogctl(bench, "run abort " + sock(bench)).code == 0);
  // Not interrupted any more: bad_request, naming the state.
  auto aborted = fogctl(bench, "run resume " + std::to_string(run) + " " + sock(bench));
  CHECK(aborted.code == 2);
  CHECK_THAT(aborted.err, Catch::Contains("is aborted"));
}

TEST_CASE("e2e fogctl: a run's end the store refused is shown as not yet recorded, then recorded once it is") {
  require_sim();
  require_fogctl();
  LiveBench bench(20.0, {{"safe_setpoint_c", 15}});
  LineClient c(bench.socket());
  REQUIRE(c.ok());
  const auto run = bench.start_run(c, "short", {"SIM-0001"});
  REQUIRE(bench.wait_status(c, [](const json& r) { return r["run"].is_object() && r["run"]["elapsed_s"] > 5; }, 60s)
              ["result"]["run"].is_object());
  // Another process takes the store's write lock: the next second waits out the busy timeout
  // (5 s) and fails, the run is aborted, and its end cannot be written either.
  sqlite3* other = nullptr;
  REQUIRE(sqlite3_open((bench.dir / "fogbench.db").c_str(), &other) == SQLITE_OK);
  REQUIRE(sqlite3_exec(other, "BEGIN IMMEDIATE", nullptr, nullptr, nullptr) == SQLITE_OK);
  auto s = bench.wait_status(c, [](const json& r) { return r["last_run"].is_object(); }, 60s);
  REQUIRE(s["result"]["last_run"].is_object());
  CHECK(s["result"]["last_run"]["recorded"] == false);
  CHECK(s["result"]["setpoint_c"] == 15.0);

  auto st = fogctl(bench, "status " + sock(bench));
  REQUIRE(st.code == 0);
  CHECK_THAT(st.out, Catch::Contains("last run " + std::to_string(run) + ": aborted (storage failed (busy)"));
  CHECK_THAT(st.out, Catch::Contains("NOT yet recorded"));
  auto g = fogctl(bench, "run get " + std::to_string(run) + " --json " + sock(bench));
  REQUIRE(g.code == 0);
  const json gj = json::parse(g.out);
  CHECK(gj["run"]["state"] == "aborted");  // from the daemon's memory; the file still says running
  CHECK(gj["run"]["recorded"] == false);
  auto gt = fogctl(bench, "run get " + std::to_string(run) + " " + sock(bench));
  REQUIRE(gt.code == 0);
  CHECK_THAT(gt.out, Catch::Contains("NOT yet recorded"));
  // run.list says the same, and a list of the runs stored as running no longer holds it.
  auto list = c.call({{"cmd", "run.list"}});
  REQUIRE(code_of(list) == "ok");
  REQUIRE(list["result"]["runs"].size() == 1);
  CHECK(list["result"]["runs"][0]["state"] == "aborted");
  CHECK(list["result"]["runs"][0]["recorded"] == false);
  CHECK(c.call({{"cmd", "run.list"}, {"state", "running"}})["result"]["runs"].empty());

  REQUIRE(sqlite3_exec(other, "ROLLBACK", nullptr, nullptr, nullptr) == SQLITE_OK);
  sqlite3_close(other);
  auto done = bench.wait_status(c, [](const json& r) { return r["last_run"]["recorded"] == true; }, 60s);
  CHECK(done["result"]["last_run"]["recorded"] == true);
  auto after = fogctl(bench, "run get " + std::to_string(run) + " --json " + sock(bench));
  REQUIRE(after.code == 0);
  const json aj = json::parse(after.out);
  CHECK(aj["run"]["state"] == "aborted");
  CHECK_FALSE(aj["run"].contains("recorded"));
  CHECK(aj["quality"].is_array());
  auto st2 = fogctl(bench, "status " + sock(bench));
  CHECK(st2.out.find("NOT yet recorded") == std::string::npos);
}

TEST_CASE("e2e fogctl: run start --slot puts a serial in a bench slot per run, and the next run another") {
  require_sim();
  require_fogctl();
  LiveBench bench(20.0);  // the simulator's configuration: slots A (SIM-0001) and B (SIM-0002) by index
  auto start = fogctl(bench, "run start " + sock(bench) + " --profile short --slot B=FOG-0042 --json");
  INFO(start.err);
  REQUIRE(start.code == 0);
  const auto first = json::parse(start.out)["run_id"].get<std::int64_t>();

  auto sj = fogctl(bench, "status --json " + sock(bench));
  REQUIRE(sj.code == 0);
  const json s = json::parse(sj.out);
  CHECK(s["run"]["units"] == json{"FOG-0042"});
  CHECK(s["run"]["slots"] == json{"B"});
  REQUIRE(s["units"].size() == 2);
  CHECK(s["units"][0]["slot"] == "A");
  CHECK(s["units"][0]["serial"] == "SIM-0001");  // not in the run: its configured default
  CHECK(s["units"][1]["slot"] == "B");
  CHECK(s["units"][1]["serial"] == "FOG-0042");
  auto st = fogctl(bench, "status " + sock(bench));
  REQUIRE(st.code == 0);
  CHECK(row_of(st.out, "FOG-0042").at(0) == "B");  // slot unit gyro_dph ...

  // Refusals name what is wrong, exit 2, and start nothing (the run is still the first).
  auto bad = fogctl(bench, "run start " + sock(bench) + " --profile short --slot C=FOG-0043");
  CHECK(bad.code == 2);
  CHECK(bad.err.find("slots.C: no such slot on this bench (slots: A, B)") != std::string::npos);
  bad = fogctl(bench, "run start " + sock(bench) + " --profile short --slot B");
  CHECK(bad.code == 2);
  CHECK(bad.err.find("--slot: expected SLOT=SERIAL") != std::string::npos);
  bad = fogctl(bench, "run start " + sock(bench) + " --profile short --slot A=FOG-1 --slot A=FOG-2");
  CHECK(bad.code == 2);
  CHECK(bad.err.find("slot A given twice") != std::string::npos);
  bad = fogctl(bench, "run start " + sock(bench) + " --profile short --unit FOG-0043");
  CHECK(bad.code == 2);
  CHECK(bad.err.find("--slot A=FOG-0043") != std::string::npos);
  bad = fogctl(bench, "plan validate paper " + sock(bench) + " --slot C=FOG-0043");
  INFO(bad.err);
  CHECK(bad.code == 2);
  CHECK(bad.err.find("slots.C") != std::string::npos);

  REQUIRE(fogctl(bench, "run abort " + sock(bench) + " --reason next").code == 0);
  LineClient c(bench.socket());
  REQUIRE(c.ok());
  bench.wait_state(c, first, {"aborted"}, 60s);
  auto gj = fogctl(bench, "run get " + std::to_string(first) + " --json " + sock(bench));
  REQUIRE(gj.code == 0);
  json g = json::parse(gj.out);
  CHECK(g["run"]["units"] == json{"FOG-0042"});
  CHECK(g["run"]["slots"] == json{"B"});
  CHECK(g["identity"]["units"][0]["serial"] == "FOG-0042");

  // The next gyro in the same slot: no configuration change, no restart.
  start = fogctl(bench, "run start " + sock(bench) + " --profile short --slot B=FOG-0043 --json");
  INFO(start.err);
  REQUIRE(start.code == 0);
  const auto second = json::parse(start.out)["run_id"].get<std::int64_t>();
  CHECK(second != first);
  gj = fogctl(bench, "run get " + std::to_string(second) + " --json " + sock(bench));
  REQUIRE(gj.code == 0);
  g = json::parse(gj.out);
  CHECK(g["run"]["units"] == json{"FOG-0043"});
  CHECK(g["run"]["slots"] == json{"B"});
  sj = fogctl(bench, "status --json " + sock(bench));
  REQUIRE(sj.code == 0);
  CHECK(json::parse(sj.out)["units"][1]["serial"] == "FOG-0043");
  REQUIRE(fogctl(bench, "run abort " + sock(bench) + " --reason done").code == 0);
}
