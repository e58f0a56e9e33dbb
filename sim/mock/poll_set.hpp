// One round of the mock bench's poll() loop: the descriptors to watch, each with what to do
// when it is ready. Every part of the bench (Modbus server, CAN bus, control socket) adds its
// own, so the loop itself knows none of them.
#pragma once

#include <poll.h>

#include <cerrno>

#include <functional>
#include <vector>

namespace fogbench::mock {

class PollSet {
 public:
  using Handler = std::function<void(short revents)>;
  void clear() {
    fds_.clear();
    handlers_.clear();
  }
  void add(int fd, short events, Handler handler) {
    fds_.push_back({fd, events, 0});
    handlers_.push_back(std::move(handler));
  }
  // Waits up to timeout_ms; false on a poll() error other than EINTR (errno says which).
  bool wait(int timeout_ms) { return ::poll(fds_.data(), fds_.size(), timeout_ms) >= 0 || errno == EINTR; }
  // Calls the handler of each ready descriptor, in the order added, while keep_going() holds.
  template <class KeepGoing>
  void dispatch(KeepGoing&& keep_going) {
    for (std::size_t i = 0; i < fds_.size() && keep_going(); ++i) {
      if (fds_[i].revents != 0) handlers_[i](fds_[i].revents);
    }
  }

 private:
  std::vector<pollfd> fds_;
  std::vector<Handler> handlers_;
};

}  // namespace fogbench::mock
