// A blocking line-oriented client connection (TCP, or a serial port through termios) for the
// ASCII chamber controllers: one command out, one reply line back, within a deadline; reconnection
// under exponential backoff; every failure a value naming the device, the command and what came
// back. Run on a worker thread, never an event loop.
#pragma once

#include <chrono>
#include <functional>
#include <string>
#include <string_view>

#include "fogbench/drivers/backoff.hpp"
#include "fogbench/drivers/config.hpp"
#include "fogbench/drivers/error.hpp"

namespace fogbench::drivers {

class LineLink {
 public:
  using Clock = std::function<std::chrono::steady_clock::time_point()>;

  // No I/O here: the first exchange connects. `name` prefixes messages ("chamber espec");
  // `line_end` is appended to each command; a reply ends at `terminator`, and CR and LF around
  // it are stripped. An empty clock means std::chrono::steady_clock::now.
  LineLink(LineEndpoint endpoint, std::string name, std::string line_end, char terminator,
           Clock clock = {});
  ~LineLink();
  LineLink(const LineLink&) = delete;
  LineLink& operator=(const LineLink&) = delete;

  // Connects if not connected; while a backoff delay runs returns `connection` at once.
  Result<void> connect();
  void disconnect() noexcept;
  bool is_connected() const noexcept { return fd_ >= 0; }

  // Sends `command` and reads one reply line. Fails with timeout (no whole line in
  // response_timeout_ms; the message shows any half line received), or connection (refused,
  // reset, closed); either closes the link and advances the backoff, so a late reply is never
  // taken for the next command's answer. `shown` is the command as messages show it.
  Result<std::string> exchange(std::string_view command, std::string_view shown);

  // "chamber espec (tcp 127.0.0.1:57732)": how every message starts.
  std::string prefix() const;
  const LineEndpoint& endpoint() const noexcept { return endpoint_; }
  const Backoff& backoff() const noexcept { return backoff_; }

 private:
  std::unexpected<DriverError> link_failed(ErrorCode code, std::string message);
  Result<void> open_tcp(std::chrono::steady_clock::time_point deadline);
  Result<void> open_serial();

  LineEndpoint endpoint_;
  std::string name_;
  std::string line_end_;
  char terminator_;
  Clock clock_;
  Backoff backoff_;
  int fd_ = -1;
  std::string pending_;  // bytes read past the last reply's terminator
};

}  // namespace fogbench::drivers
