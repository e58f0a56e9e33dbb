// Newline-delimited framing of the command protocol, without any socket: bytes go in, whole
// lines come out, and a line longer than the limit is reported once so the session can send an
// error and close. Tested in tests/daemon/framing_test.cpp.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <string_view>

namespace fogbench::daemon {

// A line may be at most this long, newline excluded (docs/protocol.md).
inline constexpr std::size_t kMaxLineBytes = 1024 * 1024;

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

}  // namespace fogbench::daemon
