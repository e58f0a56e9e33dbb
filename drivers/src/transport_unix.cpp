// Gyro frames over an AF_UNIX SOCK_SEQPACKET socket: the mock bench's CAN bus. Message
// boundaries are kept, so each datagram is exactly one struct can_frame.
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <memory>

#include "datagram_reader.hpp"
#include "fogbench/drivers/can_transport.hpp"

namespace fogbench::drivers {

Result<std::unique_ptr<CanTransport>> open_unix_seqpacket(const std::string& path) {
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  if (path.empty() || path.size() >= sizeof addr.sun_path) {
    return fail(ErrorCode::config, "unix:" + path + ": socket path must be 1..107 characters");
  }
  std::memcpy(addr.sun_path, path.c_str(), path.size() + 1);
  const int fd = ::socket(AF_UNIX, SOCK_SEQPACKET | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
  if (fd < 0) {
    return fail(ErrorCode::io, "unix:" + path + ": socket: " + std::strerror(errno));
  }
  // A non-blocking connect to a unix socket completes at once or fails at once (no handshake
  // to wait for); EAGAIN means the listener's backlog is full.
  if (::connect(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof addr) != 0) {
    const int err = errno;
    ::close(fd);
    return fail(ErrorCode::connection, "unix:" + path + ": connect: " + std::strerror(err));
  }
  return std::make_unique<detail::DatagramTransport>(fd, "unix:" + path);
}

}  // namespace fogbench::drivers
