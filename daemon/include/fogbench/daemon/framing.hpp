// Newline-delimited framing of the command protocol, without any socket: bytes go in, whole
// lines come out, and a line longer than the limit is reported once so the session can send an
// error and close; then a line becomes a request object, with the protocol's limits on nesting
// and duplicate keys checked while it is parsed. Tested in tests/daemon/framing_test.cpp.
#pragma once

#include <cstddef>
#include <expected>
#include <optional>
#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

namespace fogbench::daemon {

// A line may be at most this long, newline excluded (docs/protocol.md).
inline constexpr std::size_t kMaxLineBytes = 1024 * 1024;
// A request may nest arrays and objects at most this deep; the request object itself is level
// 1 (docs/protocol.md). nlohmann::json copies, dumps and destroys a value recursively, so a
// deeper one (100,000 '[' fit in a line) would overflow the stack: it is refused while it is
// parsed, before any of it is built.
inline constexpr std::size_t kMaxDepth = 64;

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
  std::size_t start_ = 0;  // consumed bytes at the front, erased lazily
  bool spent_ = false;
};

// One protocol line as JSON, the way the server reads every request: the value, or the reason
// it is refused as `bad_json` ("not a JSON value", a nesting deeper than kMaxDepth naming the
// column where it passed the limit, or a key that appears twice in one object, named with the
// path to it). The parse stops at the first violation, so nothing deeper than kMaxDepth is ever
// built, copied or destroyed.
std::expected<nlohmann::json, std::string> parse_request(std::string_view line,
                                                         std::size_t max_depth = kMaxDepth);

}  // namespace fogbench::daemon
