// Newline-delimited framing of the command protocol, without any socket: bytes go in, whole
// lines come out, and a line longer than the limit is reported once so the session can send an
// error and close; then a line becomes a JSON value, with the protocol's limits on nesting and
// duplicate keys checked while it is parsed. The daemon reads requests with it, fogctl the
// daemon's messages. Tested in tests/protocol/framing_test.cpp.
#pragma once

#include <cstddef>
#include <expected>
#include <optional>
#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

#include "fogbench/protocol/protocol.hpp"

namespace fogbench::protocol {

class LineSplitter {
 public:
  enum class Status { line, incomplete, too_long };

  explicit LineSplitter(std::size_t max_line_bytes = kMaxLineBytes) : max_(max_line_bytes) {}

  // Appends received bytes.
  void feed(std::string_view bytes) { buffer_.append(bytes); }

  // The next complete line (without "\n" and a trailing "\r"): `line` with it in `out`;
  // `incomplete` when no newline has arrived yet; `too_long` when the line in progress already
  // exceeds the limit (the splitter is then spent: the caller closes the connection).
  Status next(std::string& out);

  std::size_t buffered() const { return buffer_.size() - start_; }

 private:
  std::size_t max_;
  std::string buffer_;
  std::size_t start_ = 0;    // consumed bytes at the front, erased lazily
  std::size_t scanned_ = 0;  // bytes before this hold no newline (searched already)
  bool spent_ = false;
};

// One protocol line as JSON, the way the daemon reads every request (and fogctl every message):
// the value, or why it is refused (the daemon replies `bad_json`): "not a JSON value", a nesting
// deeper than max_depth naming the column where it passed the limit, or a key that appears twice
// in one object, named with the path to it. The parse stops at the first violation, so nothing
// deeper than max_depth is ever built, copied or destroyed.
std::expected<nlohmann::json, std::string> parse_line(std::string_view line, std::size_t max_depth = kMaxDepth);

}  // namespace fogbench::protocol
