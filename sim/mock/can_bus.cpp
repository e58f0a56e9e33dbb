// See can_bus.hpp.
#include "can_bus.hpp"

#include <spdlog/spdlog.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>

#include "serial_gyro.hpp"
#include "unix_socket.hpp"

namespace fogbench::mock {

namespace {
// Requested socket send buffer of a CAN reader: about 25,000 frames (the kernel charges each
// 16-byte datagram some 300 bytes), so a reader that pauses for a scheduler hiccup of a second
// at 20,000 frames/s loses nothing.
constexpr int can_sndbuf_bytes = 8 << 20;
}  // namespace

std::expected<void, std::string> CanBus::listen(const std::string& path) {
  auto fd = listen_unix(path, SOCK_SEQPACKET);
  if (!fd) return std::unexpected(fd.error());
  path_ = path;
  fd_ = *fd;
  return {};
}

void CanBus::accept() {
  const int fd = ::accept4(fd_, nullptr, nullptr, SOCK_CLOEXEC);
  if (fd < 0) return;
  // Root may pass the system's cap (SO_SNDBUFFORCE); others get what wmem_max allows.
  if (::setsockopt(fd, SOL_SOCKET, SO_SNDBUFFORCE, &can_sndbuf_bytes, sizeof can_sndbuf_bytes) != 0) {
    ::setsockopt(fd, SOL_SOCKET, SO_SNDBUF, &can_sndbuf_bytes, sizeof can_sndbuf_bytes);
  }
  std::lock_guard lock(mutex_);
  readers_.push_back(fd);
  spdlog::info("CAN client connected ({} now)", readers_.size());
}

void CanBus::send(std::span<const ::can_frame> frames) {
  if (frames.empty()) return;
  if (tap_ != nullptr) tap_->send(frames);
  std::lock_guard lock(mutex_);
  for (auto it = readers_.begin(); it != readers_.end();) {
    std::size_t done = 0;
    bool gone = false;
    while (done < frames.size()) {
      constexpr std::size_t batch = 64;
      mmsghdr msgs[batch]{};
      iovec iov[batch]{};
      const std::size_t n = std::min(batch, frames.size() - done);
      for (std::size_t i = 0; i < n; ++i) {
        iov[i].iov_base = const_cast<::can_frame*>(&frames[done + i]);
        iov[i].iov_len = sizeof(::can_frame);
        msgs[i].msg_hdr.msg_iov = &iov[i];
        msgs[i].msg_hdr.msg_iovlen = 1;
      }
      const int r = ::sendmmsg(*it, msgs, static_cast<unsigned>(n), MSG_DONTWAIT | MSG_NOSIGNAL);
      if (r < 0) {
        if (errno == EINTR) continue;
        if (errno != EAGAIN && errno != EWOULDBLOCK && errno != ENOBUFS) gone = true;
        break;
      }
      done += static_cast<std::size_t>(r);
    }
    if (gone) {
      ::close(*it);
      it = readers_.erase(it);
      spdlog::info("CAN client left ({} now)", readers_.size());
      continue;
    }
    if (done < frames.size()) {
      dropped_ += frames.size() - done;
      warn_slow_reader(frames.size() - done);
    }
    ++it;
  }
}

// Called with mutex_ held.
void CanBus::warn_slow_reader(std::size_t n) {
  const auto now = std::chrono::steady_clock::now();
  if (now - last_slow_warning_ < std::chrono::seconds(1)) return;
  last_slow_warning_ = now;
  spdlog::warn("a CAN client is not reading fast enough: {} frame(s) dropped ({} in all)", n, dropped_);
}

std::size_t CanBus::readers() const {
  std::lock_guard lock(mutex_);
  return readers_.size();
}

std::uint64_t CanBus::dropped() const {
  std::lock_guard lock(mutex_);
  return dropped_;
}

void CanBus::close() {
  {
    std::lock_guard lock(mutex_);
    for (int fd : readers_) ::close(fd);
    readers_.clear();
  }
  if (fd_ >= 0) {
    ::close(fd_);
    ::unlink(path_.c_str());
    fd_ = -1;
  }
}

}  // namespace fogbench::mock
