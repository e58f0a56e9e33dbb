// The line splitter of the command protocol.
#include "fogbench/daemon/framing.hpp"

namespace fogbench::daemon {

LineSplitter::Status LineSplitter::next(std::string& out) {
  if (spent_) return Status::too_long;
  const auto nl = buffer_.find('\n', start_);
  if (nl == std::string::npos) {
    if (buffer_.size() - start_ > max_) {
      spent_ = true;
      buffer_.clear();
      start_ = 0;
      return Status::too_long;
    }
    // Compact only when nothing is pending from the front, so a burst of lines is O(n).
    if (start_ > 0) {
      buffer_.erase(0, start_);
      start_ = 0;
    }
    return Status::incomplete;
  }
  std::size_t len = nl - start_;
  if (len > max_) {
    spent_ = true;
    buffer_.clear();
    start_ = 0;
    return Status::too_long;
  }
  if (len > 0 && buffer_[nl - 1] == '\r') --len;
  out.assign(buffer_, start_, len);
  start_ = nl + 1;
  return Status::line;
}

}  // namespace fogbench::daemon
