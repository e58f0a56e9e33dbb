// Dispatch of the command protocol (docs/protocol.md): a request line in, a reply message out,
// without any socket. The server owns the connections; this maps JSON to JSON, so the unit tests
// and the golden transcripts in tests/golden/ replay it directly.
#pragma once

#include <functional>
#include <memory>
#include <span>
#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

#include "fogbench/daemon/station.hpp"

namespace fogbench::daemon {

// What a connection carries between requests.
struct SessionState {
  bool subscribed = false;  // receives "sample" and "event" messages
  // Commands that change something (Access::control in the command table) only on the local
  // socket, whose file mode says who may use it; the TCP port, the web panel's WebSocket and
  // its /api are for reading (or with the token).
  bool may_control = true;
  // On a connection that may only read: the token (socket.tcp.token) that lets a request
  // control anyway when it carries it in its `token` field. Empty: none is accepted.
  std::string control_token;
  // The unix socket's peer (SO_PEERCRED): its user name, or "uid N" when it has none; empty on
  // TCP. A run started without `operator` records it as its operator (docs/daemon.md).
  std::string peer_user;
  // A network client's address (no port): its share of the analysis worker is counted by it
  // (socket.max_analyses_per_address). Empty on the unix socket.
  std::string address;
};

// What a socket command needs of its connection (docs/protocol.md, "Read-only and control
// commands"): `read` commands are served everywhere, `control` ones (they change something) on
// a connection that may control, or with the token on one that may only read. No default: a
// command's entry in the table does not compile without one.
enum class Access { read, control };

// One socket command as the handler's table (handler.cpp) declares it. That table is the only
// list of command names in the daemon: dispatch, the access check, the choice of the worker and
// the tests all read it, so a command absent from it is `unknown_command` everywhere.
struct CommandInfo {
  std::string_view name;
  Access access;
  bool offloaded;  // run on the Offload (Handler::offloaded), not on the loop
};
// Every socket command, in the table's order.
std::span<const CommandInfo> commands();
// The command called `name`; nullptr when there is none.
const CommandInfo* find_command(std::string_view name);
// The commands that change something (Access::control); the others only read.
bool is_control_command(std::string_view cmd);

struct CommandHandlers;

class Handler {
 public:
  explicit Handler(Station& station) : station_(station) {}

  // The first message on every connection.
  static nlohmann::json hello();
  // A message as sent: one protocol line, newline included. Invalid UTF-8 in a string (a
  // profile parser's quote of a cut multi-byte character, say) is replaced rather than thrown.
  using Line = std::shared_ptr<const std::string>;
  static Line to_line(const nlohmann::json& message);
  using Done = std::function<void(Line reply)>;

  // Parses a line and dispatches it; never throws, whatever the line holds. The reply goes to
  // `done`: at once for most commands; for the long ones (offloaded()) once the station's
  // Offload has run them, later and on the loop thread, serialised off it when it is large. A
  // session waits for it before its next request, so replies keep the order of the requests.
  void handle_line(std::string_view line, SessionState& session, Done done);
  void handle(const nlohmann::json& request, SessionState& session, Done done);
  // The same, for an Offload that runs inline (tests, golden transcripts, the fuzzer): the reply.
  nlohmann::json handle_line(std::string_view line, SessionState& session);
  nlohmann::json handle(const nlohmann::json& request, SessionState& session);

  // The commands handed to the Offload (CommandInfo::offloaded): the analyses (model.fit,
  // model.verify, model.compare, model.diagnose, model.add_term) and the reads that may be
  // large (run.samples, run.get, cert.get).
  static bool offloaded(std::string_view cmd);

  static nlohmann::json reply(const nlohmann::json& id, nlohmann::json result);
  static nlohmann::json error(const nlohmann::json& id, ErrorCode code, const std::string& message);
  // The reply to a line over kMaxLineBytes; the connection is closed after it.
  static nlohmann::json too_long();

 private:
  // The table's handlers (handler.cpp), one per command.
  friend struct CommandHandlers;
  Station& station_;
};

}  // namespace fogbench::daemon
