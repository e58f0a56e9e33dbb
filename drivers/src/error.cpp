// Names of the driver error codes and the number formatting used in error messages.
#include "fogbench/drivers/error.hpp"

#include <charconv>
#include <cmath>

namespace fogbench::drivers {

std::string_view to_string(ErrorCode code) noexcept {
  switch (code) {
    case ErrorCode::timeout: return "timeout";
    case ErrorCode::connection: return "connection";
    case ErrorCode::protocol: return "protocol";
    case ErrorCode::config: return "config";
    case ErrorCode::out_of_range: return "out_of_range";
    case ErrorCode::open_circuit: return "open_circuit";
    case ErrorCode::corrupt: return "corrupt";
    case ErrorCode::end_of_stream: return "end_of_stream";
    case ErrorCode::io: return "io";
  }
  return "unknown";
}

std::string DriverError::to_string() const {
  std::string out{drivers::to_string(code)};
  out += ": ";
  out += message;
  return out;
}

bool is_link_failure(const DriverError& e) noexcept {
  return e.code == ErrorCode::timeout || e.code == ErrorCode::connection;
}

std::string format_number(double value) {
  if (std::isnan(value)) return "nan";
  if (std::isinf(value)) return value > 0 ? "inf" : "-inf";
  char buf[64];
  // Whole numbers as integers ("2000000 ohm" reads better than "2e+06 ohm"); others shortest.
  if (std::fabs(value) < 1e15 && std::floor(value) == value) {
    auto [end, ec] = std::to_chars(buf, buf + sizeof buf, static_cast<long long>(value));
    if (ec == std::errc{}) return std::string(buf, end);
  }
  auto [end, ec] = std::to_chars(buf, buf + sizeof buf, value);
  if (ec != std::errc{}) return "?";
  return std::string(buf, end);
}

}  // namespace fogbench::drivers
