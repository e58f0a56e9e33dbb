// A scripted line peer for the ASCII chamber drivers' tests: a thread that serves a TCP listener
// on 127.0.0.1 (ephemeral port) or the master side of a pseudo-terminal, reads command lines
// (ended by CR, a LF after it skipped) and sends whatever `answer` returns for each, raw: a
// reply in another dialect, an error line, half a line, or nothing at all. Every wait has a
// deadline, so a broken driver fails a test instead of hanging it.
#pragma once

#include <catch2/catch.hpp>

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <poll.h>
#include <stdlib.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <functional>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace linepeer {

class LinePeer {
 public:
  using Answer = std::function<std::string(const std::string& line)>;
  enum class Kind { tcp, pty };

  explicit LinePeer(Answer answer, Kind kind = Kind::tcp) : answer_(std::move(answer)) {
    if (kind == Kind::tcp) {
      listen_fd_ = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
      REQUIRE(listen_fd_ >= 0);
      sockaddr_in addr{};
      addr.sin_family = AF_INET;
      addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
      REQUIRE(::bind(listen_fd_, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0);
      REQUIRE(::listen(listen_fd_, 4) == 0);
      socklen_t len = sizeof addr;
      ::getsockname(listen_fd_, reinterpret_cast<sockaddr*>(&addr), &len);
      port_ = ntohs(addr.sin_port);
    } else {
      master_fd_ = ::posix_openpt(O_RDWR | O_NOCTTY | O_CLOEXEC);
      REQUIRE(master_fd_ >= 0);
      REQUIRE(::grantpt(master_fd_) == 0);
      REQUIRE(::unlockpt(master_fd_) == 0);
      device_ = ::ptsname(master_fd_);
    }
    thread_ = std::thread([this] { run(); });
  }

  ~LinePeer() {
    stop_ = true;
    thread_.join();
    if (listen_fd_ >= 0) ::close(listen_fd_);
    if (master_fd_ >= 0) ::close(master_fd_);
  }

  std::uint16_t port() const { return port_; }
  const std::string& device() const { return device_; }
  // The command lines received so far, in order.
  std::vector<std::string> received() const {
    std::lock_guard lock(mutex_);
    return received_;
  }

 private:
  void serve(int fd) {
    std::string in;
    while (!stop_) {
      pollfd p{fd, POLLIN, 0};
      if (::poll(&p, 1, 20) <= 0) continue;
      char buf[256];
      const auto n = ::read(fd, buf, sizeof buf);
      if (n <= 0 && fd == master_fd_) {
        // EIO while no one holds the terminal's slave side open: wait for the driver.
        std::this_thread::sleep_for(std::chrono::milliseconds(10));
        continue;
      }
      if (n <= 0) return;
      in.append(buf, static_cast<std::size_t>(n));
      std::size_t at;
      while ((at = in.find('\r')) != std::string::npos) {
        std::string line = in.substr(0, at);
        in.erase(0, at + 1);
        if (!in.empty() && in.front() == '\n') in.erase(0, 1);
        {
          std::lock_guard lock(mutex_);
          received_.push_back(line);
        }
        const std::string reply = answer_(line);
        if (!reply.empty() && ::write(fd, reply.data(), reply.size()) < 0) return;
      }
    }
  }

  void run() {
    if (master_fd_ >= 0) {
      serve(master_fd_);
      return;
    }
    while (!stop_) {
      pollfd p{listen_fd_, POLLIN, 0};
      if (::poll(&p, 1, 20) <= 0) continue;
      const int fd = ::accept4(listen_fd_, nullptr, nullptr, SOCK_CLOEXEC);
      if (fd < 0) continue;
      serve(fd);
      ::close(fd);
    }
  }

  Answer answer_;
  int listen_fd_ = -1, master_fd_ = -1;
  std::uint16_t port_ = 0;
  std::string device_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
  mutable std::mutex mutex_;
  std::vector<std::string> received_;
};

}  // namespace linepeer
