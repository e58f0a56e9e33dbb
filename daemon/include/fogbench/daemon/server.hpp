// fogbenchd's event loop: one Boost.Asio io_context that owns the signal set, the command
// socket acceptors and sessions, the acquisition schedule and the gyro bus descriptor, plus the
// worker thread that libmodbus's blocking calls force (chamber and thermistors) and the
// analysis worker (fits, verifications, large reads; offload.hpp).
#pragma once

#include <expected>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>

#include "fogbench/daemon/config.hpp"

namespace fogbench::daemon {

struct ServerOptions {
  double time_scale = 1.0;  // daemon seconds per wall second; > 1 only when simulated
  // The configuration file (absolute), read again on SIGHUP and config.reload; none: no reload.
  std::filesystem::path config_path;
};

class Server {
 public:
  Server(DaemonConfig config, ServerOptions options);
  ~Server();
  Server(const Server&) = delete;
  Server& operator=(const Server&) = delete;

  // Why start() failed, and fogbenchd's exit status for it (docs/daemon.md): 2 when another
  // fogbenchd holds the store or answers on the socket, 1 for any other start-up failure.
  struct StartError {
    std::string message;
    int exit_code = 1;
  };
  // Locks the store (one daemon per store), binds the sockets, opens the store and recovers
  // interrupted runs, in that order: a start that fails changes nothing in the store. Errors say
  // what failed.
  std::expected<void, StartError> start();
  // Runs until SIGTERM or SIGINT (or stop()); returns when the chamber has been sent to its
  // safe setpoint and every connection is closed. 0 on a clean stop.
  int run();
  // Asks the loop to stop as on SIGTERM (thread-safe).
  void stop();
  // Runs `f` on the event loop (thread-safe): fogbenchd's systemd watchdog proves with it that
  // the loop still turns.
  void post(std::function<void()> f);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace fogbench::daemon
