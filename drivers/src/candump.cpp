// candump -l log lines: parsing and formatting of classic CAN frames.
#include "fogbench/drivers/candump.hpp"

#include <cstdio>
#include <cstring>

namespace fogbench::drivers {
namespace {

int hex_value(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

}  // namespace

std::optional<LogFrame> parse_candump_line(std::string_view line) {
  while (!line.empty() && (line.back() == '\n' || line.back() == '\r' || line.back() == ' ')) {
    line.remove_suffix(1);
  }
  LogFrame out;
  std::memset(&out.frame, 0, sizeof out.frame);
  // "(seconds.micros)"
  if (line.size() < 4 || line[0] != '(') return std::nullopt;
  const auto close = line.find(')');
  if (close == std::string_view::npos) return std::nullopt;
  const auto stamp = line.substr(1, close - 1);
  const auto dot = stamp.find('.');
  if (dot == std::string_view::npos || dot == 0 || stamp.size() - dot - 1 != 6) return std::nullopt;
  std::int64_t sec = 0;
  for (char c : stamp.substr(0, dot)) {
    if (c < '0' || c > '9' || sec > 1'000'000'000'000) return std::nullopt;
    sec = sec * 10 + (c - '0');
  }
  std::int64_t usec = 0;
  for (char c : stamp.substr(dot + 1)) {
    if (c < '0' || c > '9') return std::nullopt;
    usec = usec * 10 + (c - '0');
  }
  // Microseconds since the epoch must fit an int64: 9.2e12 s. Reject anything past 1e12 s
  // (year 33658) rather than overflow (found by the candump fuzzer).
  if (sec >= 1'000'000'000'000) return std::nullopt;
  out.time_us = sec * 1'000'000 + usec;

  // " interface "
  std::string_view rest = line.substr(close + 1);
  if (rest.empty() || rest[0] != ' ') return std::nullopt;
  rest.remove_prefix(1);
  const auto space = rest.find(' ');
  if (space == std::string_view::npos || space == 0) return std::nullopt;
  out.interface = std::string(rest.substr(0, space));
  rest.remove_prefix(space + 1);
  // Newer candump versions may append a direction flag after another space: ignore it.
  if (const auto tail = rest.find(' '); tail != std::string_view::npos) rest = rest.substr(0, tail);

  // "ID#DATA"
  const auto hash = rest.find('#');
  if (hash != 3 && hash != 8) return std::nullopt;
  std::uint32_t id = 0;
  for (char c : rest.substr(0, hash)) {
    const int v = hex_value(c);
    if (v < 0) return std::nullopt;
    id = (id << 4) | static_cast<std::uint32_t>(v);
  }
  if (hash == 3) {
    if (id > CAN_SFF_MASK) return std::nullopt;
  } else if (id & CAN_ERR_FLAG) {
    // An error frame's id is the error flag and error classes only: no EFF or RTR bits.
    if (id & ~(CAN_ERR_FLAG | CAN_ERR_MASK)) return std::nullopt;
  } else {
    if (id > CAN_EFF_MASK) return std::nullopt;
    id |= CAN_EFF_FLAG;
  }
  std::string_view data = rest.substr(hash + 1);
  if (!data.empty() && data[0] == '#') return std::nullopt;  // CAN FD
  if (!data.empty() && data[0] == 'R') {
    id |= CAN_RTR_FLAG;
    if (data.size() == 2 && data[1] >= '0' && data[1] <= '8') {
      out.frame.can_dlc = static_cast<std::uint8_t>(data[1] - '0');
    } else if (data.size() != 1) {
      return std::nullopt;
    }
    out.frame.can_id = id;
    return out;
  }
  std::size_t n = 0;
  for (std::size_t i = 0; i < data.size();) {
    if (data[i] == '.') {  // candump's optional byte separator
      ++i;
      continue;
    }
    if (data[i] == '_') break;  // "_L" length code for DLC > 8: not used by the gyros
    if (i + 1 >= data.size() || n >= 8) return std::nullopt;
    const int hi = hex_value(data[i]);
    const int lo = hex_value(data[i + 1]);
    if (hi < 0 || lo < 0) return std::nullopt;
    out.frame.data[n++] = static_cast<std::uint8_t>((hi << 4) | lo);
    i += 2;
  }
  out.frame.can_id = id;
  out.frame.can_dlc = static_cast<std::uint8_t>(n);
  return out;
}

std::string format_candump_line(std::int64_t time_us, std::string_view interface,
                                const ::can_frame& frame) {
  static constexpr char digits[] = "0123456789ABCDEF";
  char stamp[40];
  std::snprintf(stamp, sizeof stamp, "(%010lld.%06lld) ",
                static_cast<long long>(time_us / 1'000'000), static_cast<long long>(time_us % 1'000'000));
  std::string out = stamp;
  out += interface;
  out += ' ';
  std::uint32_t id = 0;
  int width = 3;
  if (frame.can_id & CAN_ERR_FLAG) {
    id = frame.can_id & (CAN_ERR_MASK | CAN_ERR_FLAG);
    width = 8;
  } else if (frame.can_id & CAN_EFF_FLAG) {
    id = frame.can_id & CAN_EFF_MASK;
    width = 8;
  } else {
    id = frame.can_id & CAN_SFF_MASK;
  }
  for (int shift = (width - 1) * 4; shift >= 0; shift -= 4) out += digits[(id >> shift) & 0xF];
  out += '#';
  if (frame.can_id & CAN_RTR_FLAG) {
    out += 'R';
    // A remote frame's requested length, so that the line reads back to the same frame.
    if (frame.can_dlc > 0 && frame.can_dlc <= 8) out += static_cast<char>('0' + frame.can_dlc);
    return out;
  }
  for (int i = 0; i < frame.can_dlc && i < 8; ++i) {
    out += digits[frame.data[i] >> 4];
    out += digits[frame.data[i] & 0xF];
  }
  return out;
}

}  // namespace fogbench::drivers
