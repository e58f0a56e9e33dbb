// The configuration's reload on the live mock bench (docs/daemon.md, "Reloading the
// configuration"): SIGHUP while a run acquires applies a slot's default serial and a connection
// limit, names the restart-only key and loses no second of the run; a broken file (bad JSON, an
// unknown key) through `fogctl config reload` is refused naming the key and line, and changes
// nothing.
#include "live_bench.hpp"

#include <signal.h>
#include <sys/wait.h>

#include "fogbench/daemon/config_reload.hpp"
#include "fogbench/storage/samples.hpp"
#include "fogbench/storage/store.hpp"

using namespace fogbench;
using namespace fogbench::daemon::test;
using namespace fogbench::daemon::test::live;
using nlohmann::json;
using namespace std::chrono_literals;

namespace {

std::string slurp(const std::filesystem::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

struct Out {
  int code = -1;
  std::string out, err;
};

Out fogctl(const LiveBench& bench, const std::string& args) {
  const auto out = bench.dir / "fogctl.out", err = bench.dir / "fogctl.err";
  const std::string cmd = "cd '" + bench.dir.string() + "' && env -u FOGBENCH_TOKEN '" + (kBin / "fogctl").string() +
                          "' " + args + " --socket '" + bench.socket().string() + "' >'" + out.string() + "' 2>'" +
                          err.string() + "'";
  const int st = std::system(cmd.c_str());
  return {WIFEXITED(st) ? WEXITSTATUS(st) : -1, slurp(out), slurp(err)};
}

json config_of(const LiveBench& bench) { return json::parse(slurp(bench.dir / "fogbenchd.json")); }
void write_config(const LiveBench& bench, const std::string& text) { std::ofstream(bench.dir / "fogbenchd.json") << text; }

// Waits until the daemon's log holds `text`.
bool log_has(const LiveBench& bench, const std::string& text, std::chrono::seconds timeout) {
  const auto deadline = SteadyClock::now() + timeout;
  while (SteadyClock::now() < deadline) {
    if (slurp(bench.dir / "fogbenchd.log").find(text) != std::string::npos) return true;
    std::this_thread::sleep_for(50ms);
  }
  return false;
}

bool acquiring(const json& state) { return state == "settling" || state == "running"; }

}  // namespace

TEST_CASE("e2e config reload: SIGHUP applies a default serial and a limit during a run, a broken file changes nothing") {
  require_sim();
  require_fogctl();
  LiveBench bench(20.0);  // slots A (SIM-0001) and B (SIM-0002)
  LineClient c(bench.socket());
  REQUIRE(c.ok());
  const auto run = bench.start_run(c, "exp1", {"SIM-0001"});  // slot B stays idle
  auto s = bench.wait_status(c, [](const json& r) {
    return r["run"].is_object() && r["run"]["elapsed_s"].get<double>() >= 10.0;
  }, 60s);
  REQUIRE(s["result"]["run"]["elapsed_s"].get<double>() >= 10.0);

  // A default serial, a connection limit and a restart-only key, then SIGHUP.
  json cfg = config_of(bench);
  const json original = cfg;
  cfg["drivers"]["units"][1]["serial"] = "FOG-0777";
  cfg["socket"]["max_clients"] = 9;
  cfg["socket"]["path"] = "elsewhere.sock";
  write_config(bench, cfg.dump(2));
  REQUIRE(::kill(bench.daemon->pid(), SIGHUP) == 0);

  s = bench.wait_status(c, [](const json& r) { return r["units"][1]["serial"] == "FOG-0777"; }, 20s);
  INFO(s.dump());
  CHECK(s["result"]["units"][1]["serial"] == "FOG-0777");
  CHECK(s["result"]["units"][0]["serial"] == "SIM-0001");  // in the run
  CHECK(s["result"]["run"]["id"] == run);
  CHECK(acquiring(s["result"]["run"]["state"]));
  CHECK(s["result"]["run"]["slots"] == json{"A"});
  CHECK(log_has(bench, "needs a restart (old value kept): socket.path", 10s));
  CHECK(log_has(bench, "drivers.units[1].serial", 1s));
  CHECK(log_has(bench, "socket.max_clients", 1s));
  CHECK_FALSE(std::filesystem::exists(bench.dir / "elsewhere.sock"));

  // The same through fogctl: the report names the restart-only key (still differing); the
  // run's audit trail records the reload that changed something under it.
  auto again = fogctl(bench, "config reload --json");
  INFO(again.err);
  REQUIRE(again.code == 0);
  const json rep = json::parse(again.out);
  CHECK(rep["applied"].empty());
  REQUIRE(rep["needs_restart"].size() == 1);
  CHECK(rep["needs_restart"][0]["key"] == "socket.path");
  CHECK(rep["active_run"] == run);
  auto human = fogctl(bench, "config reload");
  CHECK(human.code == 0);
  CHECK_THAT(human.out, Catch::Contains("needs a restart: socket.path"));
  auto g = c.call({{"cmd", "run.get"}, {"run_id", run}});
  bool audited = false;
  for (const auto& e : g["result"]["events"])
    audited = audited || (e["kind"] == "command" && e["detail"].value("cmd", "") == "config.reload");
  CHECK(audited);

  // A broken file: bad JSON, then an unknown key. Refused with the line, nothing changes.
  write_config(bench, "{\n  \"simulated\": true\n  \"storage\": {}\n}\n");
  auto bad = fogctl(bench, "config reload");
  CHECK(bad.code == 2);
  CHECK_THAT(bad.err, Catch::Contains("invalid_config") && Catch::Contains("line 3, column 11: not valid JSON"));
  json unknown = cfg;
  unknown["socket"]["max_clientz"] = 4;
  unknown["drivers"]["units"][1]["serial"] = "FOG-0888";
  const std::string text = unknown.dump(2);
  write_config(bench, text);
  bad = fogctl(bench, "config reload");
  CHECK(bad.code == 2);
  const auto line = daemon::line_of_key(text, "socket.max_clientz");
  REQUIRE(line.has_value());
  CHECK_THAT(bad.err, Catch::Contains("socket.max_clientz (line " + std::to_string(*line) + "): unknown field"));
  CHECK_THAT(bad.err, Catch::Contains("unchanged"));
  CHECK(log_has(bench, "socket.max_clientz (line", 5s));
  s = c.call({{"cmd", "status"}});
  CHECK(s["result"]["units"][1]["serial"] == "FOG-0777");  // the old configuration stands
  CHECK(s["result"]["run"]["id"] == run);
  CHECK(acquiring(s["result"]["run"]["state"]));
  write_config(bench, original.dump(2));

  // No second lost: the run's stored seconds are 0, 1, 2, ... up to its end.
  std::this_thread::sleep_for(1s);
  auto ab = c.call({{"cmd", "run.abort"}, {"reason", "test done"}});
  REQUIRE(ab.contains("result"));
  auto end = bench.wait_state(c, run, {"aborted"}, 30s);
  REQUIRE(end["result"]["run"]["state"] == "aborted");
  storage::OpenOptions ro;
  ro.read_only = true;
  auto store = storage::Store::open(bench.dir / "fogbench.db", ro);
  REQUIRE(store.has_value());
  auto rows = store->get_samples(run, 0, 0, 100000);
  REQUIRE(rows.has_value());
  REQUIRE(rows->size() > 20);
  std::size_t out_of_step = 0;
  for (std::size_t i = 0; i < rows->size(); ++i) out_of_step += (*rows)[i].t_s != static_cast<double>(i);
  CHECK(out_of_step == 0);
  const json last = c.call({{"cmd", "status"}})["result"]["last_run"];
  INFO(last.dump());
  REQUIRE(last["run_id"] == run);
  CHECK(static_cast<double>(rows->size()) >= last["elapsed_s"].get<double>() - 1.0);
}
