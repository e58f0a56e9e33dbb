// A live mock bench for end-to-end tests: fogbench-sim and fogbenchd in a fresh temp dir,
// accelerated, with the sim's control socket for injecting faults. Every wait has a deadline.
#pragma once

#include "fixture.hpp"
#include "process.hpp"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cstdlib>
#include <set>

namespace fogbench::daemon::test::live {

using nlohmann::json;
using namespace std::chrono_literals;

inline const std::filesystem::path kBin = FOGBENCH_BIN_DIR;

// A fresh temp dir with the mock bench and the daemon running on it.
struct LiveBench {
  std::filesystem::path dir;
  std::unique_ptr<Process> sim, daemon;
  json ready_sim, ready_daemon;
  double time_scale;
  json config_patch;  // merged into the daemon's configuration (merge_patch)
  // Run before fogbenchd's own argv, e.g. {"/usr/bin/prlimit", "--nofile=64", "--"}; the
  // command must exec fogbenchd in its own process (the stop signals go to that pid).
  std::vector<std::string> daemon_prefix;
  // The daemon paces the simulated world (fogbench-sim --paced, the daemon's `sim_clock`).
  bool paced = false;
  // The mock bench's per-unit physics (fogbench-sim --config, docs/mock-bench.md); null: none.
  json sim_config;
  // More fogbench-sim options, after the harness's own (e.g. {"--chamber-dialect", "espec"}).
  std::vector<std::string> sim_args;

  explicit LiveBench(double k, json patch = json::object(), bool paced_clock = false, json sim_cfg = nullptr,
                     std::vector<std::string> extra_sim_args = {})
      : time_scale(k), config_patch(std::move(patch)), paced(paced_clock), sim_config(std::move(sim_cfg)),
        sim_args(std::move(extra_sim_args)) {
    char tmpl[] = "/tmp/fogbench-e2e-XXXXXX";
    dir = ::mkdtemp(tmpl);
    std::filesystem::create_directories(dir / "profiles");
    for (auto src : {std::filesystem::path(FOGBENCH_SOURCE_DIR) / "profiles", golden_dir() / "profiles"})
      for (const auto& e : std::filesystem::directory_iterator(src))
        if (e.path().extension() == ".profile")
          std::filesystem::copy_file(e.path(), dir / "profiles" / e.path().filename(),
                                     std::filesystem::copy_options::overwrite_existing);
    start_sim();
    write_config();
    start_daemon();
  }
  ~LiveBench() {
    daemon.reset();
    sim.reset();
    if (!std::getenv("FOGBENCH_KEEP_TEST_DIRS")) {
      std::error_code ec;
      std::filesystem::remove_all(dir, ec);
    }
  }

  void start_sim() {
    std::vector<std::string> argv{(kBin / "fogbench-sim").string(), "--modbus-port", "0", "--thermistor-port", "0",
                                  "--can-socket", (dir / "can.sock").string(), "--units", "2", "--seed", "7",
                                  "--coil", "lumped",  // the paper's model is the exact truth: exp1's fit passes on exp2
                                  "--time-scale", std::to_string(time_scale), "--log-level", "warn",
                                  "--control", control().string()};
    if (paced) argv.push_back("--paced");
    argv.insert(argv.end(), sim_args.begin(), sim_args.end());
    if (!sim_config.is_null()) {
      std::ofstream(dir / "sim.json") << sim_config.dump(2);
      argv.push_back("--config");
      argv.push_back((dir / "sim.json").string());
    }
    sim = std::make_unique<Process>(argv, dir / "sim.log");
    const auto line = sim->read_line(60s);
    INFO("fogbench-sim log in " << (dir / "sim.log"));
    REQUIRE(!line.empty());
    ready_sim = json::parse(line);
    REQUIRE(ready_sim.contains("drivers_config"));
  }

  void write_config() {
    json c = {{"simulated", true},
              {"storage", {{"path", "fogbench.db"}, {"synchronous", "normal"}}},
              {"socket", {{"path", "fogbenchd.sock"}}},
              {"chamber_limits", {{"min_c", -30}, {"max_c", 60}, {"max_rate_c_per_min", 3}}},
              {"safe_setpoint_c", 20},
              {"profile_dir", "profiles"},
              {"drivers", ready_sim["drivers_config"]}};
    if (paced) c["sim_clock"] = control().string();
    // A sim serving a rate table (--rate-table-port): the daemon drives it.
    if (ready_sim.contains("rate_table_config") && !ready_sim["rate_table_config"].is_null())
      c["rate_table"] = ready_sim["rate_table_config"];
    c.merge_patch(config_patch);
    std::ofstream(dir / "fogbenchd.json") << c.dump(2);
  }

  void start_daemon() {
    std::vector<std::string> argv = daemon_prefix;
    for (std::string a : {(kBin / "fogbenchd").string(), std::string("--config"), (dir / "fogbenchd.json").string(),
                          std::string("--time-scale"), std::to_string(time_scale)})
      argv.push_back(a);
    daemon = std::make_unique<Process>(argv, dir / "fogbenchd.log");
    const auto line = daemon->read_line(60s);
    INFO("fogbenchd log in " << (dir / "fogbenchd.log"));
    REQUIRE(!line.empty());
    ready_daemon = json::parse(line);
  }

  std::filesystem::path socket() const { return dir / "fogbenchd.sock"; }
  std::filesystem::path control() const { return dir / "sim-control.sock"; }

  // One command on the mock bench's control socket (docs/mock-bench.md); its reply.
  json sim_command(const json& cmd) {
    LineClient ctl(control());
    if (!ctl.ok() || !ctl.send_raw(cmd.dump() + "\n")) return nullptr;
    auto l = ctl.line(10s);
    return l ? json::parse(*l, nullptr, false) : json(nullptr);
  }

  // Starts a run of `profile` on `units` through `c`, which must succeed; its id.
  std::int64_t start_run(LineClient& c, const std::string& profile, const std::vector<std::string>& units,
                         const std::string& purpose = "fit") {
    auto r = c.call({{"cmd", "run.start"}, {"profile", profile}, {"units", units}, {"purpose", purpose}});
    INFO(r.dump());
    REQUIRE(r.is_object());
    REQUIRE(r.contains("result"));
    return r["result"]["run_id"].get<std::int64_t>();
  }

  // Polls run.get until the run is in one of `states`; the last reply.
  json wait_state(LineClient& c, std::int64_t run, std::set<std::string> states, std::chrono::seconds timeout) {
    const auto deadline = SteadyClock::now() + timeout;
    json r;
    while (SteadyClock::now() < deadline) {
      r = c.call({{"cmd", "run.get"}, {"run_id", run}});
      if (r.is_object() && r.contains("result") && states.contains(r["result"]["run"]["state"].get<std::string>()))
        return r;
      std::this_thread::sleep_for(200ms);
    }
    return r;
  }

  // Polls status until pred holds.
  template <class Pred>
  json wait_status(LineClient& c, Pred pred, std::chrono::seconds timeout) {
    const auto deadline = SteadyClock::now() + timeout;
    json s;
    while (SteadyClock::now() < deadline) {
      s = c.call({{"cmd", "status"}});
      if (s.is_object() && s.contains("result") && pred(s["result"])) return s;
      std::this_thread::sleep_for(100ms);
    }
    return s;
  }
};

inline bool have_sim() { return std::filesystem::exists(kBin / "fogbench-sim"); }
// An end-to-end test fails when a binary it runs is missing (tests/CMakeLists.txt makes
// test_daemon depend on them): a warning and a return would pass without testing anything.
inline void require_sim() {
  INFO("fogbench-sim not built in " << kBin);
  REQUIRE(have_sim());
}
inline void require_fogctl() {
  INFO("fogctl not built in " << kBin);
  REQUIRE(std::filesystem::exists(kBin / "fogctl"));
}

// A port free a moment ago on loopback (the kernel's pick; the daemon binds it next).
inline std::uint16_t free_port() {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a);
  socklen_t len = sizeof a;
  ::getsockname(fd, reinterpret_cast<sockaddr*>(&a), &len);
  ::close(fd);
  return ntohs(a.sin_port);
}

inline std::string code_of(const json& reply) {
  if (!reply.is_object()) return "no reply";
  if (!reply.contains("error")) return "ok";
  return reply["error"]["code"];
}


}  // namespace fogbench::daemon::test::live
