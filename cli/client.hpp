// fogctl's client commands: talk to fogbenchd over its command socket (docs/protocol.md):
// status, run start/watch/list/get/abort/export, and fit/verify on a stored run (--run N).
#pragma once

#include <deque>
#include <expected>
#include <string>

#include <nlohmann/json.hpp>

#include "fogbench/model/run.hpp"

namespace CLI {
class App;
}

namespace fogbench::cli {

// $FOGBENCH_SOCKET, else /run/fogbench/fogbenchd.sock.
std::string default_socket();

// An error of the client: a protocol code ("busy", "not_found"...) or "connection", and a
// message for the user.
struct ClientError {
  std::string code;
  std::string message;
};

// A blocking connection to the daemon: requests wait for the reply with the same id; messages
// pushed meanwhile (subscriptions) are kept for next_message(). Every wait has a deadline.
class Client {
 public:
  static std::expected<Client, ClientError> connect(const std::string& socket_path, int timeout_ms = 5000);
  Client(Client&& o) noexcept;
  Client& operator=(Client&& o) noexcept;
  Client(const Client&) = delete;
  ~Client();

  // Sends {"id", "cmd", ...args} and returns the `result`, or the reply's error.
  std::expected<nlohmann::json, ClientError> call(const std::string& cmd,
                                                  nlohmann::json args = nlohmann::json::object(),
                                                  int timeout_ms = 60000);
  // The next message that is not a reply (sample, event); timeout: code "timeout".
  std::expected<nlohmann::json, ClientError> next_message(int timeout_ms);

  const nlohmann::json& hello() const { return hello_; }

 private:
  explicit Client(int fd) : fd_(fd) {}
  std::expected<nlohmann::json, ClientError> read_message(int timeout_ms);
  int fd_ = -1;
  std::string buffer_;
  std::deque<nlohmann::json> pushed_;
  std::int64_t next_id_ = 1;
  nlohmann::json hello_;
};

// All samples of a run's unit as a RunData (settle samples left out unless asked). A value
// not read is bridged from its neighbour and the sample keeps its `missing` flag, so the CSV is
// valid and fits skip it.
std::expected<model::RunData, ClientError> fetch_run(Client& c, std::int64_t run_id, int unit,
                                                     bool include_settle = false);

// Registers status, run (start, watch, list, get, abort, export) and extends fit and verify
// with --run N; `code` receives the exit code.
void add_client_commands(CLI::App& app, int& code);

}  // namespace fogbench::cli
