// Child processes for the end-to-end tests: the real fogbench-sim and fogbenchd started from
// FOGBENCH_BIN_DIR, their JSON "ready" line read from stdout with a deadline, their stderr kept
// in a log file, and a stop by SIGTERM (SIGKILL after a deadline). Plus a minimal line client
// of the command socket (the tests link the daemon library, not fogctl).
#pragma once

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/socket.h>
#include <netinet/in.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstring>
#include <filesystem>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

namespace fogbench::daemon::test {

using SteadyClock = std::chrono::steady_clock;

class Process {
 public:
  Process(std::vector<std::string> argv, const std::filesystem::path& log) {
    int out[2];
    if (::pipe2(out, O_CLOEXEC) != 0) return;
    pid_ = ::fork();
    if (pid_ == 0) {
      ::dup2(out[1], 1);
      const int err = ::open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      if (err >= 0) ::dup2(err, 2);
      std::vector<char*> args;
      for (auto& a : argv) args.push_back(a.data());
      args.push_back(nullptr);
      ::execv(args[0], args.data());
      ::_exit(127);
    }
    ::close(out[1]);
    out_ = out[0];
  }
  ~Process() {
    stop(std::chrono::seconds(10));
    if (out_ >= 0) ::close(out_);
  }

  // The first line on stdout, or empty after the deadline or if the process ended.
  std::string read_line(std::chrono::milliseconds timeout) {
    const auto deadline = SteadyClock::now() + timeout;
    for (;;) {
      const auto nl = buf_.find('\n');
      if (nl != std::string::npos) {
        std::string line = buf_.substr(0, nl);
        buf_.erase(0, nl + 1);
        return line;
      }
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - SteadyClock::now()).count();
      if (left <= 0) return {};
      pollfd p{out_, POLLIN, 0};
      if (::poll(&p, 1, static_cast<int>(left)) <= 0) continue;
      char b[4096];
      const ssize_t n = ::read(out_, b, sizeof b);
      if (n <= 0) return {};
      buf_.append(b, static_cast<std::size_t>(n));
    }
  }

  // SIGTERM, then waits up to `timeout` (SIGKILL after it). The exit status, or -1 if killed.
  int stop(std::chrono::milliseconds timeout) {
    if (pid_ <= 0) return status_;
    ::kill(pid_, SIGTERM);
    return wait(timeout);
  }
  // SIGKILL now (a crash, as far as the process can tell); waits for it.
  void kill_now() {
    if (pid_ <= 0) return;
    ::kill(pid_, SIGKILL);
    int st = 0;
    ::waitpid(pid_, &st, 0);
    pid_ = -1;
    status_ = -1;
  }
  int wait(std::chrono::milliseconds timeout) {
    if (pid_ <= 0) return status_;
    const auto deadline = SteadyClock::now() + timeout;
    int st = 0;
    while (SteadyClock::now() < deadline) {
      if (::waitpid(pid_, &st, WNOHANG) == pid_) {
        pid_ = -1;
        status_ = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
        return status_;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    ::kill(pid_, SIGKILL);
    ::waitpid(pid_, &st, 0);
    pid_ = -1;
    status_ = -1;
    return status_;
  }
  bool running() const { return pid_ > 0; }
  pid_t pid() const { return pid_; }  // to signal it (SIGSTOP/SIGCONT); -1 once reaped

 private:
  pid_t pid_ = -1;
  int out_ = -1;
  int status_ = -1;
  std::string buf_;
};

// One connection to fogbenchd's socket; reads lines with deadlines.
class LineClient {
 public:
  explicit LineClient(const std::filesystem::path& path) {
    sockaddr_un a{};
    a.sun_family = AF_UNIX;
    std::strncpy(a.sun_path, path.c_str(), sizeof a.sun_path - 1);
    fd_ = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (::connect(fd_, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0) {
      ::close(fd_);
      fd_ = -1;
    }
  }
  // To 127.0.0.1:port over TCP.
  explicit LineClient(std::uint16_t port) {
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(port);
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    fd_ = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (::connect(fd_, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0) {
      ::close(fd_);
      fd_ = -1;
    }
  }
  ~LineClient() {
    if (fd_ >= 0) ::close(fd_);
  }
  bool ok() const { return fd_ >= 0; }
  bool send_raw(const std::string& bytes) {
    std::size_t sent = 0;
    while (sent < bytes.size()) {
      const ssize_t n = ::send(fd_, bytes.data() + sent, bytes.size() - sent, MSG_NOSIGNAL);
      if (n <= 0) return false;
      sent += static_cast<std::size_t>(n);
    }
    return true;
  }
  // The next line; nullopt on timeout or when the daemon closed the connection.
  std::optional<std::string> line(std::chrono::milliseconds timeout = std::chrono::seconds(30)) {
    const auto deadline = SteadyClock::now() + timeout;
    for (;;) {
      const auto nl = buf_.find('\n');
      if (nl != std::string::npos) {
        std::string l = buf_.substr(0, nl);
        buf_.erase(0, nl + 1);
        return l;
      }
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - SteadyClock::now()).count();
      if (left <= 0) return std::nullopt;
      pollfd p{fd_, POLLIN, 0};
      if (::poll(&p, 1, static_cast<int>(left)) <= 0) continue;
      char b[65536];
      const ssize_t n = ::recv(fd_, b, sizeof b, 0);
      if (n <= 0) {
        closed_ = true;
        return std::nullopt;
      }
      buf_.append(b, static_cast<std::size_t>(n));
    }
  }
  bool closed() const { return closed_; }
  // Sends a request and returns the reply with its id (pushed messages in between are dropped).
  nlohmann::json call(nlohmann::json req, std::chrono::milliseconds timeout = std::chrono::seconds(60)) {
    const auto id = next_id_++;
    req["id"] = id;
    if (!send_raw(req.dump() + "\n")) return nullptr;
    const auto deadline = SteadyClock::now() + timeout;
    for (;;) {
      auto l = line(std::chrono::duration_cast<std::chrono::milliseconds>(deadline - SteadyClock::now()));
      if (!l) return nullptr;
      auto j = nlohmann::json::parse(*l, nullptr, false);
      if (j.is_object() && j.value("type", "") == "reply" && j["id"] == id) return j;
    }
  }

 private:
  int fd_ = -1;
  std::string buf_;
  bool closed_ = false;
  std::int64_t next_id_ = 1;
};

}  // namespace fogbench::daemon::test
