// Several gyro transports behind one file descriptor: a bench's serial gyros (each on a line of
// its own) beside its CAN bus. An epoll descriptor watches every part, so the daemon's loop waits
// on one fd as before; GyroBus routes the frames by node id as for any transport.
#include <sys/epoll.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <memory>
#include <set>
#include <utility>
#include <vector>

#include "fogbench/drivers/can_transport.hpp"

namespace fogbench::drivers {

namespace {

class MultiTransport final : public CanTransport {
 public:
  MultiTransport(int epoll_fd, std::vector<TransportPart> parts) : epoll_fd_(epoll_fd), parts_(std::move(parts)) {}
  ~MultiTransport() override { ::close(epoll_fd_); }

  int fd() const noexcept override { return epoll_fd_; }

  Result<std::size_t> read(std::vector<::can_frame>& out) override {
    // Every part is read (one with nothing returns 0); the epoll descriptor is level-triggered,
    // so it stays readable while a part still has frames (a part's read is bounded).
    std::size_t got = 0;
    for (auto& part : parts_) {
      scratch_.clear();
      auto n = part.transport->read(scratch_);
      if (!n) return n;  // names the part's device; GyroBus::reopen reopens them all
      for (const auto& f : scratch_) {
        // A part's frames of a node another part owns (the CAN bus carrying a unit that is read
        // on its serial line) are not this part's to give.
        const bool plain = (f.can_id & (CAN_EFF_FLAG | CAN_RTR_FLAG | CAN_ERR_FLAG)) == 0;
        if (plain && !part.only.empty() && !part.only.contains(static_cast<std::uint16_t>(f.can_id & CAN_SFF_MASK)))
          continue;
        if (plain && part.only.empty() && elsewhere_.contains(static_cast<std::uint16_t>(f.can_id & CAN_SFF_MASK)))
          continue;
        out.push_back(f);
        ++got;
      }
    }
    return got;
  }

  std::uint64_t malformed() const noexcept override {
    std::uint64_t n = 0;
    for (const auto& part : parts_) n += part.transport->malformed();
    return n;
  }

  std::string describe() const override {
    std::string s;
    for (const auto& part : parts_) s += (s.empty() ? "" : " + ") + part.transport->describe();
    return s;
  }

  std::vector<Event> take_events() override {
    std::vector<Event> all;
    for (auto& part : parts_) {
      for (auto& e : part.transport->take_events()) all.push_back(std::move(e));
    }
    return all;
  }

  void sample_closed() noexcept override {
    for (auto& part : parts_) part.transport->sample_closed();
  }

  void take_over(const CanTransport& previous) noexcept override {
    const auto* old = dynamic_cast<const MultiTransport*>(&previous);
    if (old == nullptr || old->parts_.size() != parts_.size()) return;
    for (std::size_t i = 0; i < parts_.size(); ++i) parts_[i].transport->take_over(*old->parts_[i].transport);
  }

  void index() {
    for (const auto& part : parts_) elsewhere_.insert(part.only.begin(), part.only.end());
  }

 private:
  int epoll_fd_;
  std::vector<TransportPart> parts_;
  std::set<std::uint16_t> elsewhere_;  // the node ids some part owns
  std::vector<::can_frame> scratch_;
};

}  // namespace

Result<std::unique_ptr<CanTransport>> combine_transports(std::vector<TransportPart> parts) {
  if (parts.empty()) return fail(ErrorCode::config, "gyro_bus: no transport to read");
  const int ep = ::epoll_create1(EPOLL_CLOEXEC);
  if (ep < 0) return fail(ErrorCode::io, std::string("gyro_bus: epoll_create1: ") + std::strerror(errno));
  for (std::size_t i = 0; i < parts.size(); ++i) {
    epoll_event ev{};
    ev.events = EPOLLIN;
    ev.data.u64 = i;
    if (::epoll_ctl(ep, EPOLL_CTL_ADD, parts[i].transport->fd(), &ev) != 0) {
      const std::string why = std::strerror(errno);
      ::close(ep);
      return fail(ErrorCode::io, parts[i].transport->describe() + ": epoll_ctl: " + why);
    }
  }
  auto t = std::make_unique<MultiTransport>(ep, std::move(parts));
  t->index();
  return t;
}

}  // namespace fogbench::drivers
