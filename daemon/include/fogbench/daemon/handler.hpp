// Dispatch of the command protocol (docs/protocol.md): a request line in, a reply message out,
// without any socket. The server owns the connections; this maps JSON to JSON, so the unit tests
// and the golden transcripts in tests/golden/ replay it directly.
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

#include "fogbench/daemon/station.hpp"

namespace fogbench::daemon {

// What a connection carries between requests.
struct SessionState {
  bool subscribed = false;  // receives "sample" and "event" messages
  // Commands that change something (is_control_command: run.start, run.abort, run.resume,
  // model.fit, model.verify, model.add_term) only on the local socket, whose file mode says who
  // may use it; the TCP port is for reading (or with the token).
  bool may_control = true;
  // On a connection that may only read: the token (socket.tcp.token) that lets a request
  // control anyway when it carries it in its `token` field. Empty: none is accepted.
  std::string control_token;
  // The unix socket's peer (SO_PEERCRED): its user name, or "uid N" when it has none; empty on
  // TCP. A run started without `operator` records it as its operator (docs/daemon.md).
  std::string peer_user;
};

// The commands that change something; the others only read (docs/protocol.md).
bool is_control_command(std::string_view cmd);

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

  // The commands handed to the Offload: the analyses (model.fit, model.verify, model.compare,
  // model.diagnose, model.add_term) and the reads that may be large (run.samples, run.get,
  // cert.get).
  static bool offloaded(std::string_view cmd);

  static nlohmann::json reply(const nlohmann::json& id, nlohmann::json result);
  static nlohmann::json error(const nlohmann::json& id, ErrorCode code, const std::string& message);
  // The reply to a line over kMaxLineBytes; the connection is closed after it.
  static nlohmann::json too_long();

 private:
  ApiResult<nlohmann::json> dispatch(const std::string& cmd, const nlohmann::json& req,
                                     SessionState& session);
  // An offloaded command: its arguments checked here, the rest submitted.
  void offload(const std::string& cmd, const nlohmann::json& req, const nlohmann::json& id, Done done);
  void offload_certificate(const nlohmann::json& req, const nlohmann::json& id, Done done);
  Station& station_;
};

}  // namespace fogbench::daemon
