// fogctl's client commands: talk to fogbenchd over its command socket (docs/protocol.md):
// status, run start/watch/list/get/abort/resume/export, and fit/verify on a stored run (--run N).
#pragma once

#include <cstdint>
#include <deque>
#include <expected>
#include <optional>
#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

#include "fogbench/model/run.hpp"
#include "fogbench/protocol/framing.hpp"

namespace CLI {
class App;
}

namespace fogbench::cli {

// $FOGBENCH_SOCKET, else /run/fogbench/fogbenchd.sock.
std::string default_socket();
// $FOGBENCH_TOKEN, else empty.
std::string default_token();

// Where the daemon listens: a unix socket path, or a TCP endpoint (`tcp_host` set).
struct Endpoint {
  std::string socket_path;
  std::string tcp_host;
  std::uint16_t tcp_port = 0;
};
// "HOST:PORT" ("[::1]:7000" for IPv6) as given to --connect; an error names what is wrong.
std::expected<Endpoint, std::string> parse_connect(const std::string& text);

// What a client call failed on.
enum class ClientErrc {
  reply,       // the daemon answered with an error reply: `reply_code` says which
  connection,  // no connection to the daemon, or it was lost
  timeout,     // no answer within the deadline
  protocol,    // the daemon speaks another protocol version, or sent a line past the limits
  bad_option,  // fogctl's own option is wrong (--connect)
};
std::string_view to_string(ClientErrc c);

// An error of the client, with a message for the user.
struct ClientError {
  ClientErrc code = ClientErrc::connection;
  std::string message;
  // code == reply: the reply's code (nullopt for one this fogctl does not know) and its wire string.
  std::optional<protocol::ErrorCode> reply_code;
  std::string reply_code_text;
};
// An error reply of the daemon (or one the client finds in what it was sent, e.g. a run without samples).
ClientError reply_error(protocol::ErrorCode code, std::string message);

// A blocking connection to the daemon: requests wait for the reply with the same id; messages
// pushed meanwhile (subscriptions) are kept for next_message(). Every wait has a deadline.
class Client {
 public:
  static std::expected<Client, ClientError> connect(const std::string& socket_path, int timeout_ms = 5000);
  // To the unix socket or the TCP endpoint; a non-empty `token` is sent with every request
  // (the daemon needs it for control commands on TCP, ignores it on the unix socket, and never
  // stores it).
  static std::expected<Client, ClientError> connect(const Endpoint& endpoint, const std::string& token = "",
                                                    int timeout_ms = 5000);
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
  static std::expected<Client, ClientError> handshake(int fd, int timeout_ms);
  // One line from the daemon: at most protocol::kMaxMessageBytes, nested at most kMaxDepth.
  std::expected<nlohmann::json, ClientError> read_message(int timeout_ms);
  int fd_ = -1;
  protocol::LineSplitter lines_{protocol::kMaxMessageBytes};
  std::deque<nlohmann::json> pushed_;
  std::string token_;
  std::int64_t next_id_ = 1;
  nlohmann::json hello_;
};

// What fetch_run does with a value the daemon could not take (NULL in the store).
enum class Gaps {
  keep,    // NaN, the sample flagged `missing`: an export writes an empty cell (docs/csv.md)
  bridge,  // the neighbour's value, the sample flagged `missing`: the daemon's own analyses do
           // this (daemon/src/analysis.cpp), so `fit --run N` fits what the station fitted
};

// All samples of a run's unit as a RunData (settle samples left out unless asked).
std::expected<model::RunData, ClientError> fetch_run(Client& c, std::int64_t run_id, int unit,
                                                     bool include_settle = false, Gaps gaps = Gaps::bridge);

// Registers status, run (start, watch, list, get, abort, resume, export) and extends fit and verify
// with --run N; `code` receives the exit code.
void add_client_commands(CLI::App& app, int& code);
// The subcommand of that name, or null.
CLI::App* find_subcommand(CLI::App& app, const std::string& name);
// --run N (with --unit and where the daemon is) on fit, verify, compare, diagnose and report:
// registered after every command (run_fetch.cpp).
void add_stored_run_options(CLI::App& app);
// fogctl profile list|validate (profile_commands.cpp).
void add_profile_commands(CLI::App& app, int& code);
// fogctl store prune (store_commands.cpp).
void add_store_commands(CLI::App& app, int& code);
// The hidden `fogctl __generate commands|bash|zsh` the build runs (generate.cpp).
void add_generate_command(CLI::App& app, int& code);

}  // namespace fogbench::cli
