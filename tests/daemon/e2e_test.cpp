// End to end over the real transports: fogbench-sim serves the chamber and thermistors over
// Modbus TCP and the gyros over a unix SEQPACKET socket; fogbenchd drives it; the test talks to
// fogbenchd's command socket. Accelerated with --time-scale; every wait has a deadline.
// Skipped (with a message) when fogbench-sim has not been built.
#include "fixture.hpp"
#include "live_bench.hpp"

#include "fogbench/protocol/framing.hpp"

#include <cstdlib>
#include <set>

using namespace fogbench::daemon::test;
using nlohmann::json;
using namespace std::chrono_literals;

using namespace fogbench::daemon::test::live;

TEST_CASE("e2e: an accelerated exp1 fit run is stored and fitted, an exp2 verify run passes") {
  require_sim();
  LiveBench bench(100.0, json::object(), true);
  INFO("test dir " << bench.dir);
  LineClient c(bench.socket());
  REQUIRE(c.ok());
  REQUIRE(json::parse(*c.line(10s))["type"] == "hello");

  const auto run = bench.start_run(c, "exp1", {"SIM-0001", "SIM-0002"});
  // exp1: a settle of at least 10 min, then 90 min: about 6000 s, 60 s at K = 100. The
  // deadline allows a loaded machine five times that.
  json done = bench.wait_state(c, run, {"completed", "aborted", "failed", "interrupted"}, 300s);
  REQUIRE(done.contains("result"));
  INFO(done["result"]["run"].dump());
  REQUIRE(done["result"]["run"]["state"] == "completed");
  const auto& samples = done["result"]["samples"];
  CHECK(samples[0].get<int>() >= 5400);
  CHECK(samples[0] == samples[1]);
  REQUIRE(done["result"]["models"].size() == 2);

  // Few samples flagged: the bench is healthy, the loop kept up.
  auto page = c.call({{"cmd", "run.samples"}, {"run_id", run}, {"unit", 1}, {"limit", 10000}});
  REQUIRE(code_of(page) == "ok");
  int flagged = 0;
  for (const auto& s : page["result"]["samples"]) flagged += s["flags"].get<int>() != 0;
  CHECK(flagged < samples[1].get<int>() / 20);

  auto m = c.call({{"cmd", "model.get"}, {"serial", "SIM-0001"}});
  REQUIRE(code_of(m) == "ok");
  CHECK(m["result"]["run_id"] == run);
  CHECK(m["result"]["model"]["terms"].size() == 2);

  auto v = c.call({{"cmd", "run.start"}, {"profile", "exp2"}, {"units", {"SIM-0001"}}, {"purpose", "verify"}});
  REQUIRE(code_of(v) == "ok");
  const auto vrun = v["result"]["run_id"].get<std::int64_t>();
  json vdone = bench.wait_state(c, vrun, {"completed", "aborted", "failed", "interrupted"}, 300s);
  REQUIRE(vdone["result"]["run"]["state"] == "completed");
  REQUIRE(vdone["result"]["verifications"].size() == 1);
  INFO(vdone["result"]["verifications"][0]["result"]["run"].dump());
  CHECK(vdone["result"]["verifications"][0]["pass"] == true);
  CHECK(vdone["result"]["verifications"][0]["model_id"] == m["result"]["id"]);
}

TEST_CASE("e2e: a run aborted mid-ramp sends the chamber back to the safe setpoint") {
  require_sim();
  LiveBench bench(50.0);
  LineClient c(bench.socket());
  REQUIRE(c.ok());
  const auto run = bench.start_run(c, "short", {"SIM-0002"});
  // Into the ramp to 25 degC, the chamber's setpoint read back above 21 degC.
  auto s = bench.wait_status(c, [](const json& r) {
    return r["run"].is_object() && r["run"]["phase"] == "heating" && r["chamber"]["setpoint_c"].is_number() &&
           r["chamber"]["setpoint_c"].get<double>() > 21.0;
  }, 120s);
  REQUIRE(s["result"]["run"]["phase"] == "heating");
  auto a = c.call({{"cmd", "run.abort"}, {"reason", "e2e test"}});
  REQUIRE(code_of(a) == "ok");
  auto back = bench.wait_status(c, [](const json& r) {
    return r["chamber"]["setpoint_c"].is_number() && r["chamber"]["setpoint_c"].get<double>() == 20.0;
  }, 30s);
  CHECK(back["result"]["chamber"]["setpoint_c"] == 20.0);
  CHECK(back["result"]["run"].is_null());
  auto g = c.call({{"cmd", "run.get"}, {"run_id", run}});
  CHECK(g["result"]["run"]["state"] == "aborted");
  CHECK(g["result"]["run"]["reason"] == "aborted by operator: e2e test");
  CHECK(g["result"]["models"].empty());
}

TEST_CASE("e2e: error replies over the socket, refusals that move and store nothing") {
  require_sim();
  LiveBench bench(20.0);
  LineClient c(bench.socket());
  REQUIRE(c.ok());
  auto hello = json::parse(*c.line(10s));
  CHECK(hello["type"] == "hello");
  CHECK(hello["protocol"] == 1);

  // Let the chamber reach the safe setpoint first, so "nothing moved" is observable.
  auto s0 = bench.wait_status(c, [](const json& r) { return r["chamber"]["setpoint_c"] == 20.0; }, 30s);
  REQUIRE(s0["result"]["chamber"]["setpoint_c"] == 20.0);

  c.send_raw("{oops\n");
  auto bad = json::parse(*c.line());
  CHECK(bad["error"]["code"] == "bad_json");
  CHECK(code_of(c.call({{"cmd", "warp"}})) == "unknown_command");
  CHECK(code_of(c.call({{"cmd", "run.start"}, {"units", {"SIM-0001"}}})) == "bad_request");
  CHECK(code_of(c.call({{"cmd", "run.start"}, {"profile", "exp1"}, {"units", "SIM-0001"}})) == "bad_request");
  CHECK(code_of(c.call({{"cmd", "run.get"}, {"run_id", "one"}})) == "bad_request");
  CHECK(code_of(c.call({{"cmd", "run.start"}, {"profile", "exp1"}, {"units", {"SIM-0001"}}, {"purpose", "verify"}})) ==
        "unknown_serial");
  CHECK(code_of(c.call({{"cmd", "run.start"}, {"profile", "exp1"}, {"units", {"FOG-4242"}}})) == "unknown_serial");
  CHECK(code_of(c.call({{"cmd", "run.start"}, {"profile", "qualification"}, {"units", {"SIM-0001"}}})) == "limits");
  CHECK(code_of(c.call({{"cmd", "run.start"}, {"profile", "hot"}, {"units", {"SIM-0001"}}})) == "limits");
  CHECK(c.call({{"cmd", "run.list"}})["result"]["runs"].empty());
  auto s1 = c.call({{"cmd", "status"}});
  CHECK(s1["result"]["chamber"]["setpoint_c"] == 20.0);
  CHECK(s1["result"]["run"].is_null());

  REQUIRE(code_of(c.call({{"cmd", "run.start"}, {"profile", "exp1"}, {"units", {"SIM-0001"}}})) == "ok");
  CHECK(code_of(c.call({{"cmd", "run.start"}, {"profile", "exp2"}, {"units", {"SIM-0002"}}})) == "busy");
  CHECK(code_of(c.call({{"cmd", "run.abort"}})) == "ok");

  // A second client is unaffected by the first's line over 1 MiB, which is closed after its error.
  LineClient other(bench.socket());
  REQUIRE(other.ok());
  c.send_raw(std::string(fogbench::protocol::kMaxLineBytes + 10, 'x'));
  std::optional<std::string> reply;
  for (auto l = c.line(30s); l; l = c.line(30s)) reply = l;  // the hello/earlier lines, then the error
  REQUIRE(reply.has_value());
  CHECK(json::parse(*reply)["error"]["code"] == "bad_request");
  CHECK(c.closed());
  CHECK(code_of(other.call({{"cmd", "status"}})) == "ok");
}

TEST_CASE("e2e: SIGTERM mid-run ends the run as aborted and leaves the chamber at the safe setpoint") {
  require_sim();
  LiveBench bench(50.0);
  std::int64_t run = 0;
  {
    LineClient c(bench.socket());
    REQUIRE(c.ok());
    run = bench.start_run(c, "short", {"SIM-0001"});
    auto s = bench.wait_status(c, [](const json& r) {
      return r["chamber"]["setpoint_c"].is_number() && r["chamber"]["setpoint_c"].get<double>() > 21.0;
    }, 120s);
    REQUIRE(s["result"]["chamber"]["setpoint_c"].get<double>() > 21.0);
  }
  CHECK(bench.daemon->stop(30s) == 0);
  {
    // The daemon confirmed the chamber's safe setpoint on its way out (the restart below
    // commands it again, so only the first daemon's log can show it).
    std::ifstream log(bench.dir / "fogbenchd.log");
    std::stringstream ss;
    ss << log.rdbuf();
    CHECK_THAT(ss.str(), Catch::Contains("chamber left at the safe setpoint 20 C"));
  }
  bench.start_daemon();  // the same store and bench
  LineClient c(bench.socket());
  REQUIRE(c.ok());
  auto g = c.call({{"cmd", "run.get"}, {"run_id", run}});
  CHECK(g["result"]["run"]["state"] == "aborted");
  CHECK(g["result"]["run"]["reason"] == "fogbenchd stopping: SIGTERM");
  auto s = bench.wait_status(c, [](const json& r) { return r["chamber"]["setpoint_c"].is_number(); }, 30s);
  CHECK(s["result"]["chamber"]["setpoint_c"] == 20.0);
}

TEST_CASE("e2e: fogbenchd refuses --time-scale on hardware and a bad configuration, naming the field") {
  char tmpl[] = "/tmp/fogbench-e2e-XXXXXX";
  const std::filesystem::path dir = ::mkdtemp(tmpl);
  auto run = [&](json config, std::vector<std::string> extra) {
    std::ofstream(dir / "c.json") << config.dump();
    std::vector<std::string> argv = {(kBin / "fogbenchd").string(), "--config", (dir / "c.json").string()};
    argv.insert(argv.end(), extra.begin(), extra.end());
    Process p(argv, dir / "log");
    const int rc = p.wait(30s);
    std::ifstream log(dir / "log");
    std::stringstream ss;
    ss << log.rdbuf();
    return std::pair{rc, ss.str()};
  };
  json c = golden_config_json();
  c["map_dir"] = (std::filesystem::path(FOGBENCH_SOURCE_DIR) / "drivers" / "maps").string();
  c["profile_dir"] = (golden_dir() / "profiles").string();
  c["simulated"] = false;
  auto [rc1, log1] = run(c, {"--time-scale", "10"});
  CHECK(rc1 == 2);
  CHECK_THAT(log1, Catch::Contains("--time-scale 10 refused"));
  c["chamber_limits"]["max_rate_c_per_min"] = -1;
  auto [rc2, log2] = run(c, {});
  CHECK(rc2 == 2);
  CHECK_THAT(log2, Catch::Contains("chamber_limits.max_rate_c_per_min"));
  std::error_code ec;
  std::filesystem::remove_all(dir, ec);
}
