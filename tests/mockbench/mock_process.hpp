// Starts the real fogbench-sim in a private temporary directory (ephemeral Modbus ports, its
// own socket paths), reads its ready line, talks to its control socket, and stops it. Every
// wait has a deadline, so a hung bench fails a test instead of hanging the suite.
#pragma once

#include <catch2/catch.hpp>

#include <nlohmann/json.hpp>

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "fogbench/drivers/config.hpp"

#ifndef FOGBENCH_SIM_BIN
#define FOGBENCH_SIM_BIN FOGBENCH_BIN_DIR "/fogbench-sim"
#endif

extern char** environ;

namespace mockbench {

namespace fs = std::filesystem;
using nlohmann::json;
using namespace std::chrono_literals;

// Polls `done` every 10 ms until it holds or `timeout` passes; returns whether it held.
inline bool wait_for(std::chrono::milliseconds timeout, const std::function<bool()>& done) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (!done()) {
    if (std::chrono::steady_clock::now() > deadline) return false;
    std::this_thread::sleep_for(10ms);
  }
  return true;
}

class MockProcess {
 public:
  // Extra options are appended after the harness's own (ports 0, sockets in a temp dir).
  explicit MockProcess(std::vector<std::string> extra = {}) {
    char tmpl[] = "/tmp/fogbench-mockbench-XXXXXX";
    REQUIRE(::mkdtemp(tmpl) != nullptr);
    dir_ = tmpl;
    std::vector<std::string> args = {FOGBENCH_SIM_BIN, "--modbus-port", "0", "--thermistor-port", "0",
                                     "--can-socket", (dir_ / "can.sock").string(),
                                     "--control", (dir_ / "control.sock").string(), "--log-level", "debug"};
    args.insert(args.end(), extra.begin(), extra.end());
    int out[2];
    REQUIRE(::pipe2(out, O_CLOEXEC) == 0);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_adddup2(&actions, out[1], STDOUT_FILENO);
    posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, (dir_ / "stderr.log").c_str(),
                                     O_WRONLY | O_CREAT | O_TRUNC, 0644);
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    const int rc = ::posix_spawn(&pid_, argv[0], &actions, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&actions);
    ::close(out[1]);
    stdout_fd_ = out[0];
    REQUIRE(rc == 0);
    const std::string line = read_line(stdout_fd_, 30s);
    INFO("fogbench-sim stderr:\n" << log());
    REQUIRE_FALSE(line.empty());
    ready_ = json::parse(line);
    REQUIRE(ready_["event"] == "ready");
  }

  ~MockProcess() {
    if (pid_ > 0) {
      ::kill(pid_, SIGTERM);
      if (wait_exit(5s) < -1) {
        ::kill(pid_, SIGKILL);
        ::waitpid(pid_, nullptr, 0);
      }
    }
    if (stdout_fd_ >= 0) ::close(stdout_fd_);
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }

  const json& ready() const { return ready_; }
  std::uint16_t chamber_port() const { return ready_["chamber"]["port"].get<std::uint16_t>(); }
  std::uint16_t thermistor_port() const { return ready_["thermistors"]["port"].get<std::uint16_t>(); }
  std::string can_socket() const { return ready_["can_socket"].get<std::string>(); }
  std::string control_path() const { return ready_["control"].get<std::string>(); }
  const fs::path& dir() const { return dir_; }

  std::string log() const {
    std::ifstream in(dir_ / "stderr.log");
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
  }

  // One request on a fresh control connection; its reply line, parsed.
  json control(const json& request) const {
    const int fd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
    sockaddr_un addr{};
    addr.sun_family = AF_UNIX;
    const auto path = control_path();
    std::strncpy(addr.sun_path, path.c_str(), sizeof addr.sun_path - 1);
    REQUIRE(::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0);
    const std::string line = request.dump() + "\n";
    REQUIRE(::send(fd, line.data(), line.size(), MSG_NOSIGNAL) == static_cast<ssize_t>(line.size()));
    const std::string reply = read_line(fd, 10s);
    ::close(fd);
    INFO("request " << request.dump());
    REQUIRE_FALSE(reply.empty());
    return json::parse(reply);
  }

  json status() const { return control({{"cmd", "status"}}); }

  // Switches a fault and requires the bench to accept it.
  void fault(json command) const {
    command["cmd"] = "fault";
    const json reply = control(command);
    INFO(command.dump() << " -> " << reply.dump());
    REQUIRE(reply["ok"] == true);
  }

  // Waits until the simulated clock has passed `time_s`.
  void wait_sim_time(double time_s, std::chrono::milliseconds timeout = 30s) const {
    const bool ok = wait_for(timeout, [&] { return status()["time_s"].get<double>() >= time_s; });
    INFO("waiting for simulated time " << time_s << " s");
    REQUIRE(ok);
  }
  double sim_time() const { return status()["time_s"].get<double>(); }

  // Waits for the process to exit; its exit status, or -2 when it is still running at the deadline.
  int wait_exit(std::chrono::milliseconds timeout) {
    int status = 0;
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    while (std::chrono::steady_clock::now() < deadline) {
      const pid_t r = ::waitpid(pid_, &status, WNOHANG);
      if (r == pid_) {
        pid_ = -1;
        return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
      }
      std::this_thread::sleep_for(10ms);
    }
    return -2;
  }
  pid_t pid() const { return pid_; }

  // The shipped example configuration pointed at this bench: its units, registers and node ids
  // unchanged, so the tests also check that the bench serves what the example declares.
  fogbench::drivers::DriversConfig example_config(int response_timeout_ms = 500) const {
    std::ifstream in(FOGBENCH_SOURCE_DIR "/drivers/examples/mock-bench.json");
    REQUIRE(in);
    json j = json::parse(in);
    j["chamber"]["modbus"]["port"] = chamber_port();
    j["thermistors"]["modbus"]["port"] = thermistor_port();
    for (auto* m : {&j["chamber"]["modbus"], &j["thermistors"]["modbus"]}) {
      (*m)["response_timeout_ms"] = response_timeout_ms;
      // Reconnect soon: tests wait on real time.
      (*m)["backoff"] = {{"initial_ms", 20}, {"max_ms", 200}, {"multiplier", 2}};
    }
    j["gyro_bus"]["transport"] = "unix:" + can_socket();
    auto cfg = fogbench::drivers::parse_drivers_config(j, FOGBENCH_SOURCE_DIR "/drivers/maps");
    INFO((cfg ? std::string() : cfg.error().to_string()));
    REQUIRE(cfg.has_value());
    return *cfg;
  }

 private:
  static std::string read_line(int fd, std::chrono::milliseconds timeout) {
    std::string line;
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    char c = 0;
    while (true) {
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
      if (left.count() <= 0) return {};
      pollfd p{fd, POLLIN, 0};
      if (::poll(&p, 1, static_cast<int>(left.count())) <= 0) continue;
      const auto n = ::read(fd, &c, 1);
      if (n <= 0) return {};
      if (c == '\n') return line;
      line += c;
    }
  }

  fs::path dir_;
  pid_t pid_ = -1;
  int stdout_fd_ = -1;
  json ready_;
};

}  // namespace mockbench
