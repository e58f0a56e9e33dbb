// fogbenchd as a systemd service (issue 15): sd_notify over a real unix datagram socket
// (READY=1, STATUS=, WATCHDOG=1 while the loop turns), the journal's line format when stderr
// is the journal, and --check-config.
#include "../daemon/live_bench.hpp"

#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <sys/wait.h>

#include <cstdlib>
#include <fstream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "fogbench/daemon/systemd.hpp"

using namespace fogbench::daemon::test;
using namespace fogbench::daemon::test::live;
using namespace std::chrono_literals;
namespace sd = fogbench::daemon::systemd;

namespace {

// systemd's side of the protocol: a bound AF_UNIX datagram socket.
struct NotifySocket {
  std::filesystem::path path;
  int fd = -1;
  explicit NotifySocket(const std::filesystem::path& p) : path(p) {
    fd = ::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    sockaddr_un a{};
    a.sun_family = AF_UNIX;
    std::strncpy(a.sun_path, p.c_str(), sizeof a.sun_path - 1);
    REQUIRE(::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0);
    timeval tv{1, 0};
    ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  }
  ~NotifySocket() {
    ::close(fd);
    std::filesystem::remove(path);
  }
  // The next datagram, waiting up to `timeout`; empty when none came.
  std::string receive(std::chrono::seconds timeout) {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    char buf[4096];
    while (std::chrono::steady_clock::now() < deadline) {
      const ssize_t n = ::recv(fd, buf, sizeof buf, 0);
      if (n > 0) return std::string(buf, static_cast<std::size_t>(n));
    }
    return {};
  }
};

std::string slurp(const std::filesystem::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

}  // namespace

TEST_CASE("systemd: notify sends one datagram to the socket it is given, and nothing without one") {
  char tmpl[] = "/tmp/fogbench-notify-XXXXXX";
  const std::filesystem::path dir = ::mkdtemp(tmpl);
  {
    NotifySocket s(dir / "notify");
    CHECK(sd::notify_to(s.path.string(), "READY=1\nSTATUS=serving"));
    CHECK(s.receive(5s) == "READY=1\nSTATUS=serving");
    ::unsetenv("NOTIFY_SOCKET");
    CHECK_FALSE(sd::notify("READY=1"));
    ::setenv("NOTIFY_SOCKET", s.path.c_str(), 1);
    CHECK(sd::notify("WATCHDOG=1"));
    CHECK(s.receive(5s) == "WATCHDOG=1");
    ::unsetenv("NOTIFY_SOCKET");
  }
  CHECK_FALSE(sd::notify_to((dir / "nobody").string(), "READY=1"));  // no listener: false, no throw
  CHECK_FALSE(sd::notify_to("relative", "READY=1"));
  ::setenv("WATCHDOG_USEC", "30000000", 1);
  CHECK(sd::watchdog_interval() == std::chrono::microseconds(30000000));
  ::setenv("WATCHDOG_PID", "1", 1);  // another process's watchdog
  CHECK_FALSE(sd::watchdog_interval());
  ::unsetenv("WATCHDOG_PID");
  ::setenv("WATCHDOG_USEC", "x", 1);
  CHECK_FALSE(sd::watchdog_interval());
  ::unsetenv("WATCHDOG_USEC");
  std::filesystem::remove_all(dir);
}

TEST_CASE("systemd: fogbenchd says READY=1 once serving, pings the watchdog, logs in the journal's format") {
  require_sim();
  LiveBench bench(20.0);
  // Restarted as systemd starts it: NOTIFY_SOCKET, WATCHDOG_USEC, and stderr the journal (its
  // log file's device and inode in JOURNAL_STREAM, as systemd sets them for the stream).
  bench.daemon.reset();
  NotifySocket notify(bench.dir / "notify");
  const auto log = bench.dir / "fogbenchd.log";
  std::ofstream(log).close();
  struct stat st {};
  REQUIRE(::stat(log.c_str(), &st) == 0);
  const std::string stream = std::to_string(st.st_dev) + ":" + std::to_string(st.st_ino);
  ::setenv("NOTIFY_SOCKET", notify.path.c_str(), 1);
  ::setenv("WATCHDOG_USEC", "400000", 1);  // pings every 0.2 s
  ::setenv("JOURNAL_STREAM", stream.c_str(), 1);
  bench.start_daemon();
  ::unsetenv("NOTIFY_SOCKET");
  ::unsetenv("WATCHDOG_USEC");
  ::unsetenv("JOURNAL_STREAM");
  const std::string ready = notify.receive(30s);
  CHECK_THAT(ready, Catch::StartsWith("READY=1\nSTATUS=serving on "));
  std::string ping;
  for (int i = 0; i < 50 && ping != "WATCHDOG=1"; ++i) ping = notify.receive(10s);
  CHECK(ping == "WATCHDOG=1");
  bench.daemon.reset();  // SIGTERM
  std::string last;
  bool stopping = false;
  for (int i = 0; i < 200; ++i) {
    auto m = notify.receive(1s);
    if (m.empty()) break;
    if (m.starts_with("STOPPING=1")) stopping = true;
    last = m;
  }
  CHECK(stopping);
  CHECK_THAT(last, Catch::StartsWith("STATUS=stopped"));
  // Every line "<N>text": a syslog priority, no timestamp of spdlog's, no blank line.
  const std::string text = slurp(log);
  REQUIRE_FALSE(text.empty());
  std::istringstream lines(text);
  std::size_t n = 0;
  for (std::string l; std::getline(lines, l); ++n) {
    INFO(l);
    REQUIRE(l.size() > 3);
    CHECK(l[0] == '<');
    CHECK(l[2] == '>');
    CHECK(l.find("[20") == std::string::npos);  // spdlog's "[2026-..." stamp
  }
  CHECK(n > 2);
}

TEST_CASE("fogbenchd --check-config: 0 for a valid file, 2 naming the key of an invalid one") {
  require_sim();
  char tmpl[] = "/tmp/fogbench-check-XXXXXX";
  const std::filesystem::path dir = ::mkdtemp(tmpl);
  std::ofstream(dir / "bad.json") << R"({"simulated": true, "storage": {"path": "x.db"}, "socket": {"path": "s.sock"},
    "chamber_limits": {"min_c": -30, "max_c": 60, "max_rate_c_per_min": "fast"}, "safe_setpoint_c": 20, "drivers": {}})";
  auto run = [&](const std::string& args) {
    const std::string cmd = "'" + (kBin / "fogbenchd").string() + "' " + args + " >'" + (dir / "out").string() + "' 2>&1";
    const int s = std::system(cmd.c_str());
    return WIFEXITED(s) ? WEXITSTATUS(s) : -1;
  };
  CHECK(run("--check-config '" + (dir / "bad.json").string() + "'") == 2);
  // The key and its line (issue 28: --check-config names where, as a reload does).
  CHECK_THAT(slurp(dir / "out"), Catch::Contains("chamber_limits.max_rate_c_per_min (line 2)"));
  std::ofstream(dir / "comma.json") << "{\"simulated\": true,\n \"storage\": {\"path\": \"x.db\"},\n}\n";  // a trailing comma
  CHECK(run("--check-config '" + (dir / "comma.json").string() + "'") == 2);
  CHECK_THAT(slurp(dir / "out"), Catch::Contains("comma.json: line 3, column 1: not valid JSON") && Catch::Contains("a trailing comma at line 2, column 29"));
  CHECK(run("--check-config '" + (dir / "missing.json").string() + "'") == 2);
  CHECK(run("") == 2);  // neither --config nor --check-config
  {
    LiveBench bench(20.0);  // its configuration is a valid one
    CHECK(run("--check-config '" + (bench.dir / "fogbenchd.json").string() + "'") == 0);
    CHECK_THAT(slurp(dir / "out"), Catch::Contains("valid"));
  }
  CHECK(run("--version") == 0);
  std::filesystem::remove_all(dir);
}

TEST_CASE("fogbenchd --check-config: a store's folder or a profile_dir that does not exist is exit 2 naming the key, its line and the path") {
  require_sim();
  LiveBench bench(20.0);
  const auto good = nlohmann::json::parse(slurp(bench.dir / "fogbenchd.json"));
  const auto file = bench.dir / "paths.json";
  auto run = [&](const nlohmann::json& c) {
    std::ofstream(file) << c.dump(2);
    const std::string cmd = "'" + (kBin / "fogbenchd").string() + "' --check-config '" + file.string() + "' >'" +
                            (bench.dir / "out").string() + "' 2>&1";
    const int s = std::system(cmd.c_str());
    return WIFEXITED(s) ? WEXITSTATUS(s) : -1;
  };
  CHECK(run(good) == 0);
  auto c = good;
  c["storage"]["path"] = (bench.dir / "no-such-folder" / "fogbench.db").string();
  CHECK(run(c) == 2);
  auto out = slurp(bench.dir / "out");
  INFO(out);
  CHECK_THAT(out, Catch::Contains("storage.path (line ") && Catch::Contains("no-such-folder") &&
                      Catch::Contains("no such directory"));
  CHECK_FALSE(std::filesystem::exists(bench.dir / "no-such-folder"));  // nothing made
  c = good;
  c["storage"]["path"] = (bench.dir / "fogbenchd.json" / "fogbench.db").string();  // a file as its folder
  CHECK(run(c) == 2);
  CHECK_THAT(slurp(bench.dir / "out"), Catch::Contains("storage.path (line ") && Catch::Contains("is not a directory"));
  c = good;
  c["profile_dir"] = (bench.dir / "no-profiles").string();
  CHECK(run(c) == 2);
  CHECK_THAT(slurp(bench.dir / "out"), Catch::Contains("profile_dir (line ") && Catch::Contains("no-profiles: no such directory"));
  // The shipped units' StateDirectory= makes /var/lib/fogbench at start: not required before.
  c = good;
  c["storage"]["path"] = "/var/lib/fogbench/no-such-instance/fogbench.db";
  CHECK(run(c) == 0);
}

TEST_CASE("systemd: fogbenchd's STATUS= follows the run and idles, and STOPPING=1 comes at SIGTERM, before the shutdown") {
  require_sim();
  LiveBench bench(50.0);
  bench.daemon.reset();
  NotifySocket notify(bench.dir / "notify");
  ::setenv("NOTIFY_SOCKET", notify.path.c_str(), 1);
  bench.start_daemon();
  ::unsetenv("NOTIFY_SOCKET");
  CHECK_THAT(notify.receive(30s), Catch::StartsWith("READY=1\nSTATUS=serving on "));
  // Idle first, with no run stored yet.
  std::string m;
  for (int i = 0; i < 20 && !m.starts_with("STATUS=idle"); ++i) m = notify.receive(5s);
  CHECK(m == "STATUS=idle, no run stored");

  LineClient c(bench.socket());
  REQUIRE(c.ok());
  const auto run = bench.start_run(c, "short", {"SIM-0001", "SIM-0002"});
  const std::string prefix = "STATUS=run " + std::to_string(run) + " short ";
  // Lines during the run: its state, step of 6 (short.profile's), phase, elapsed/total time, units.
  std::vector<std::pair<std::string, std::chrono::steady_clock::time_point>> during;
  bool running_step = false;
  const auto deadline = std::chrono::steady_clock::now() + 120s;
  while (std::chrono::steady_clock::now() < deadline && during.size() < 40) {
    m = notify.receive(5s);
    if (!m.starts_with(prefix)) continue;
    during.emplace_back(m, std::chrono::steady_clock::now());
    INFO(m);
    CHECK_THAT(m, Catch::EndsWith(" s, SIM-0001 SIM-0002"));
    if (m.find(" running step ") != std::string::npos && m.find("/6 (") != std::string::npos) running_step = true;
    if (running_step && during.size() >= 6) break;
  }
  CHECK(running_step);
  REQUIRE(during.size() >= 3);
  // Lines of the same step and phase (the elapsed time moves): at most one every 5 s. (A
  // per-tick line at time scale 50 would be 50 a second.)
  for (std::size_t i = 1; i < during.size(); ++i) {
    const auto kind = [](const std::string& l) { return l.substr(0, l.find(", ")); };
    if (kind(during[i].first) == kind(during[i - 1].first)) {
      INFO(during[i - 1].first << " then " << during[i].first);
      CHECK(during[i].second - during[i - 1].second >= 3s);
    }
  }
  auto r = c.call({{"cmd", "run.abort"}, {"reason", "status test"}});
  REQUIRE(code_of(r) == "ok");
  for (int i = 0; i < 20 && !m.starts_with("STATUS=idle"); ++i) m = notify.receive(5s);
  CHECK(m == "STATUS=idle, last run " + std::to_string(run) + " short aborted");

  // The mock bench stopped: the daemon's shutdown waits its 5 s for the safe setpoint. STOPPING=1
  // must come at once, while the daemon is still at that work, not after it.
  REQUIRE(::kill(bench.sim->pid(), SIGSTOP) == 0);
  const auto sent = std::chrono::steady_clock::now();
  REQUIRE(::kill(bench.daemon->pid(), SIGTERM) == 0);
  std::string stopping;
  for (int i = 0; i < 20 && !stopping.starts_with("STOPPING=1"); ++i) stopping = notify.receive(2s);
  const auto got = std::chrono::steady_clock::now();
  int st = 0;
  const bool alive = ::waitpid(bench.daemon->pid(), &st, WNOHANG) == 0;
  ::kill(bench.sim->pid(), SIGCONT);
  CHECK(stopping == "STOPPING=1\nSTATUS=stopping: SIGTERM");
  CHECK(alive);
  CHECK(got - sent < 4s);
  std::string last;
  for (int i = 0; i < 50; ++i) {
    auto x = notify.receive(1s);
    if (x.empty()) break;
    last = x;
  }
  CHECK_THAT(last, Catch::StartsWith("STATUS=stopped (exit status "));
  bench.daemon->wait(30s);
}
