// Batched non-blocking reading of one-frame datagrams (SocketCAN raw and AF_UNIX SEQPACKET both
// deliver exactly one struct can_frame per datagram), so both transports share one read loop.
#pragma once

#include <linux/can.h>

#include <cstdint>
#include <vector>

#include "fogbench/drivers/error.hpp"

namespace fogbench::drivers::detail {

// Reads with recvmmsg until the socket would block or `max_frames` were read. A datagram of
// another size counts in `malformed`; a zero-length read means the peer closed (SEQPACKET has no
// empty datagrams in our protocol) and fails with `connection` when nothing else was read.
Result<std::size_t> read_frame_datagrams(int fd, std::vector<::can_frame>& out,
                                         std::uint64_t& malformed, const char* what,
                                         std::size_t max_frames = 4096);

}  // namespace fogbench::drivers::detail
