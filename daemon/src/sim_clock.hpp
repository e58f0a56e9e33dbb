// fogbenchd's side of the shared simulated clock (config "sim_clock"): a client of
// fogbench-sim's control socket that asks a paced bench (fogbench-sim --paced) to step the
// simulated world. Blocking, like libmodbus: it lives on the worker thread. docs/daemon.md,
// "Time scale"; the command is in docs/mock-bench.md.
#pragma once

#include <chrono>
#include <cstdint>
#include <expected>
#include <filesystem>
#include <string>

namespace fogbench::daemon {

class SimClock {
 public:
  SimClock(std::filesystem::path control, std::chrono::milliseconds timeout);
  ~SimClock();
  SimClock(const SimClock&) = delete;
  SimClock& operator=(const SimClock&) = delete;

  // Steps the world `seconds` simulated seconds; the simulated time after them. When the reply
  // has arrived, every gyro frame of those seconds is already in the gyro bus socket and the
  // registers show their end. Errors (no bench, a bench not paced, no reply in time) name the
  // socket; the connection is then dropped and made again at the next call.
  std::expected<double, std::string> advance(std::int64_t seconds);

 private:
  std::expected<void, std::string> connect();
  void disconnect();

  std::filesystem::path control_;
  std::chrono::milliseconds timeout_;
  int fd_ = -1;
  std::string in_;
};

}  // namespace fogbench::daemon
