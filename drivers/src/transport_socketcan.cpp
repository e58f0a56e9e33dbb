// Gyro frames from a SocketCAN interface (AF_CAN raw socket), filtered in the kernel to the
// units' standard ids so a busy bus does not wake the daemon for frames it would drop.
#include <linux/can.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <memory>

#include "datagram_reader.hpp"
#include "fogbench/drivers/can_transport.hpp"

namespace fogbench::drivers {

Result<std::unique_ptr<CanTransport>> open_socketcan(const std::string& interface,
                                                     std::span<const std::uint16_t> node_ids) {
  const std::string name = "can:" + interface;
  if (interface.empty() || interface.size() >= IFNAMSIZ) {
    return fail(ErrorCode::config, name + ": interface name must be 1..15 characters");
  }
  const int fd = ::socket(PF_CAN, SOCK_RAW | SOCK_NONBLOCK | SOCK_CLOEXEC, CAN_RAW);
  if (fd < 0) {
    // EAFNOSUPPORT: the kernel has no CAN (no can-raw module), as on a build machine.
    return fail(ErrorCode::connection, name + ": socket(PF_CAN): " + std::strerror(errno));
  }
  auto failed = [&](const char* call) {
    const int err = errno;
    ::close(fd);
    return fail(err == ENODEV ? ErrorCode::connection : ErrorCode::io,
                name + ": " + call + ": " + std::strerror(err));
  };
  ifreq ifr{};
  std::memcpy(ifr.ifr_name, interface.c_str(), interface.size() + 1);
  if (::ioctl(fd, SIOCGIFINDEX, &ifr) != 0) return failed("SIOCGIFINDEX");

  // One filter per unit: exactly this 11-bit id, standard data frames only (the EFF and RTR
  // flags are in the mask, so an extended or remote frame with the same low bits is dropped).
  std::vector<can_filter> filters;
  for (std::uint16_t id : node_ids) {
    filters.push_back({id, CAN_SFF_MASK | CAN_EFF_FLAG | CAN_RTR_FLAG});
  }
  if (!filters.empty() &&
      ::setsockopt(fd, SOL_CAN_RAW, CAN_RAW_FILTER, filters.data(),
                   static_cast<socklen_t>(filters.size() * sizeof(can_filter))) != 0) {
    return failed("setsockopt(CAN_RAW_FILTER)");
  }
  sockaddr_can addr{};
  addr.can_family = AF_CAN;
  addr.can_ifindex = ifr.ifr_ifindex;
  if (::bind(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof addr) != 0) return failed("bind");
  return std::make_unique<detail::DatagramTransport>(fd, name);
}

}  // namespace fogbench::drivers
