// The control protocol's framing and dispatch; see control.hpp.
#include "control.hpp"

namespace fogbench::mock {

using nlohmann::json;

std::string handle_line(std::string_view line, ControlHandler& handler) {
  auto error = [](const std::string& message) { return json{{"ok", false}, {"error", message}}.dump(); };
  if (line.size() > max_control_line) {
    return error("request longer than " + std::to_string(max_control_line) + " bytes");
  }
  json request;
  try {
    request = json::parse(line);
  } catch (const json::exception& e) {
    return error(std::string("not JSON: ") + e.what());
  }
  if (!request.is_object() || !request.contains("cmd") || !request["cmd"].is_string()) {
    return error("expected an object with a \"cmd\" string");
  }
  const auto cmd = request["cmd"].get<std::string>();
  if (cmd == "fault") {
    if (auto ok = handler.fault(request); !ok) return error(ok.error());
    return json{{"ok", true}}.dump();
  }
  if (cmd == "status") {
    json reply = {{"ok", true}, {"version", control_protocol_version}};
    reply.update(handler.status());
    return reply.dump();
  }
  if (cmd == "stop") {
    handler.stop();
    return json{{"ok", true}}.dump();
  }
  if (cmd == "advance") {
    std::int64_t seconds = 1;
    if (request.contains("seconds")) {
      const json& n = request["seconds"];
      if (!n.is_number_integer() || n.get<std::int64_t>() < 1 || n.get<std::int64_t>() > max_advance_s) {
        return error("advance: seconds: expected an integer 1.." + std::to_string(max_advance_s) + " (got " + n.dump() + ")");
      }
      seconds = n.get<std::int64_t>();
    }
    auto t = handler.advance(seconds);
    if (!t) return error("advance: " + t.error());
    return json{{"ok", true}, {"time_s", *t}}.dump();
  }
  return error("unknown cmd '" + cmd + "' (known: advance, fault, status, stop)");
}

}  // namespace fogbench::mock
