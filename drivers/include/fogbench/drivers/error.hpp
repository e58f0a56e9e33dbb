// Failure values shared by every driver: a code the caller branches on and a message for its log.
#pragma once

#include <expected>
#include <string>
#include <string_view>

namespace fogbench::drivers {

// What went wrong, in the terms a caller acts on. Drivers never throw across their API and never
// log: they return one of these and the daemon decides (retry, mark the sample, stop the run).
enum class ErrorCode {
  timeout,        // the peer did not answer within the configured time
  connection,     // no link: refused, reset, closed, or waiting out a reconnection backoff
  protocol,       // the peer answered, but with an exception or a malformed reply
  config,         // a configuration or register map was refused; the message names the field
  out_of_range,   // a value outside its valid or representable range (a sensor, a setpoint)
  open_circuit,   // a sensor reads as disconnected
  corrupt,        // data failed an integrity check (CRC, length)
  end_of_stream,  // a replayed log has no more frames
  io,             // an operating-system call failed for another reason (file, socket set-up)
};

std::string_view to_string(ErrorCode code) noexcept;

struct DriverError {
  ErrorCode code;
  std::string message;

  // "timeout: chamber 127.0.0.1:1502 unit 1: read input 2..3: Connection timed out"
  std::string to_string() const;
};

// A failure of the link itself (timeout, connection) rather than a reply the device refused: it
// ends a bring-up, where a refused read only fails its check.
bool is_link_failure(const DriverError& e) noexcept;

template <class T>
using Result = std::expected<T, DriverError>;

inline std::unexpected<DriverError> fail(ErrorCode code, std::string message) {
  return std::unexpected(DriverError{code, std::move(message)});
}

// Shortest decimal form of a number that reads back to the same double, for messages.
std::string format_number(double value);

}  // namespace fogbench::drivers
