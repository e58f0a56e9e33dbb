#pragma once
// A number in an error message, written as the shortest text that reads back to the same
// double (0.1, not 0.10000000000000001): the value the user typed or the file holds.

#include <charconv>
#include <string>

namespace fogbench::storage::detail {

inline std::string format_number(double v) {
  char buf[32];
  const auto res = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, res.ptr);
}

}  // namespace fogbench::storage::detail
