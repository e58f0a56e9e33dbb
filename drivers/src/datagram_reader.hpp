// Batched non-blocking reading of one-frame datagrams (SocketCAN raw and AF_UNIX SEQPACKET both
// deliver exactly one struct can_frame per datagram), so both transports are one class that
// differs only in how its socket is opened.
#pragma once

#include <linux/can.h>

#include <cstdint>
#include <string>
#include <vector>

#include "fogbench/drivers/can_transport.hpp"
#include "fogbench/drivers/error.hpp"

namespace fogbench::drivers::detail {

// Reads with recvmmsg until the socket would block or `max_frames` were read. A datagram of
// another size counts in `malformed`; a zero-length read means the peer closed (SEQPACKET has no
// empty datagrams in our protocol) and fails with `connection` when nothing else was read.
Result<std::size_t> read_frame_datagrams(int fd, std::vector<::can_frame>& out,
                                         std::uint64_t& malformed, const char* what,
                                         std::size_t max_frames = 4096);

// A connected datagram socket of frames; owns (and closes) fd. `name` is what describe()
// says and errors start with, e.g. "can:can0" or "unix:/run/fogbench/bus.sock".
class DatagramTransport final : public CanTransport {
 public:
  DatagramTransport(int fd, std::string name);
  ~DatagramTransport() override;
  DatagramTransport(const DatagramTransport&) = delete;
  DatagramTransport& operator=(const DatagramTransport&) = delete;

  int fd() const noexcept override { return fd_; }
  Result<std::size_t> read(std::vector<::can_frame>& out) override;
  std::uint64_t malformed() const noexcept override { return malformed_; }
  std::string describe() const override { return name_; }

 private:
  int fd_;
  std::string name_;
  std::uint64_t malformed_ = 0;
};

}  // namespace fogbench::drivers::detail
