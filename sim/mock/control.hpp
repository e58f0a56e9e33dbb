// The control protocol of the mock bench, without I/O: newline-delimited JSON requests on a
// unix stream socket, one JSON reply line each. The socket and the framing are the bench's
// LineServer (line_server.hpp, as for the ASCII chamber and the rate table); the dispatch
// (handle_line) never touches a socket, so it is tested on strings.
//
//   {"cmd":"fault","name":"freeze_pv","on":true}   -> {"ok":true}
//   {"cmd":"status"}                               -> {"ok":true,"time_s":...,...}
//   {"cmd":"stop"}                                 -> {"ok":true}, then the bench stops
//   {"cmd":"advance","seconds":1}                  -> {"ok":true,"time_s":...} (--paced only)
//   anything else                                  -> {"ok":false,"error":"..."}
#pragma once

#include <nlohmann/json.hpp>

#include <cstdint>
#include <expected>
#include <string>
#include <string_view>

namespace fogbench::mock {

inline constexpr int control_protocol_version = 1;
// A request line longer than this is refused and the connection closed.
inline constexpr std::size_t max_control_line = 4096;

// What the bench does for each request.
class ControlHandler {
 public:
  virtual ~ControlHandler() = default;
  // Applies a fault command ({"cmd":"fault",...}); an error message when refused.
  virtual std::expected<void, std::string> fault(const nlohmann::json& command) = 0;
  // The status fields (merged into {"ok":true,...}).
  virtual nlohmann::json status() = 0;
  virtual void stop() = 0;
  // A paced bench (--paced): steps the world `seconds` simulated seconds, sends every frame of
  // them, and returns the simulated time then. Refused when the bench keeps its own clock.
  virtual std::expected<double, std::string> advance(std::int64_t seconds) = 0;
};

// The most seconds one advance may ask for.
inline constexpr std::int64_t max_advance_s = 86400;

// Parses one request line, dispatches it and returns the reply line (without "\n").
std::string handle_line(std::string_view line, ControlHandler& handler);

}  // namespace fogbench::mock
