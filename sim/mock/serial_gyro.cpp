// See serial_gyro.hpp.
#include "serial_gyro.hpp"

#include <fcntl.h>
#include <stdlib.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "fogbench/drivers/can_frame.hpp"

namespace fogbench::mock {

std::expected<void, std::string> SerialGyroPeer::open(const std::string& link_path,
                                                      drivers::serial::FrameFormat format, std::uint16_t node_id,
                                                      double scale_dph_per_count) {
  close();
  const int fd = ::posix_openpt(O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) return std::unexpected("posix_openpt: " + std::string(std::strerror(errno)));
  if (::grantpt(fd) != 0 || ::unlockpt(fd) != 0) {
    const std::string why = std::strerror(errno);
    ::close(fd);
    return std::unexpected("pty: " + why);
  }
  // Raw on the master side too: no byte of a binary frame is taken for a control character.
  termios t{};
  if (::tcgetattr(fd, &t) == 0) {
    ::cfmakeraw(&t);
    ::tcsetattr(fd, TCSANOW, &t);
  }
  const char* name = ::ptsname(fd);
  if (name == nullptr) {
    ::close(fd);
    return std::unexpected("ptsname: " + std::string(std::strerror(errno)));
  }
  ::unlink(link_path.c_str());
  if (::symlink(name, link_path.c_str()) != 0) {
    const std::string why = std::strerror(errno);
    ::close(fd);
    return std::unexpected("symlink " + link_path + " -> " + name + ": " + why);
  }
  std::lock_guard lock(mutex_);
  master_ = fd;
  slave_ = name;
  link_ = link_path;
  format_ = std::move(format);
  node_id_ = node_id;
  scale_dph_per_count_ = scale_dph_per_count;
  have_sequence_ = false;
  return {};
}

void SerialGyroPeer::send(std::span<const ::can_frame> frames) {
  std::lock_guard lock(mutex_);
  if (master_ < 0) return;
  std::vector<std::uint8_t> out;
  for (const auto& f : frames) {
    if ((f.can_id & (CAN_EFF_FLAG | CAN_RTR_FLAG | CAN_ERR_FLAG)) != 0 || (f.can_id & CAN_SFF_MASK) != node_id_) continue;
    const auto decoded = drivers::can::decode(f);
    // A corrupt CAN frame's fields are not to be trusted: its sequence is the next one and its
    // serial frame goes out with the CRC broken.
    const std::uint8_t can_sequence = decoded ? decoded->sequence : static_cast<std::uint8_t>(last_can_sequence_ + 1);
    sequence_ += have_sequence_ ? static_cast<std::uint8_t>(can_sequence - last_can_sequence_) : can_sequence;
    have_sequence_ = true;
    last_can_sequence_ = can_sequence;
    drivers::serial::Frame frame;
    frame.sequence = sequence_;
    if (decoded) {
      frame.rate_dph = decoded->counts * scale_dph_per_count_;
      frame.status = (decoded->status & drivers::can::status::valid) ? format_.status_valid_mask : 0;
    }
    auto bytes = drivers::serial::encode(format_, frame);
    if (!decoded) {
      if (format_.crc != drivers::serial::CrcKind::none) {
        bytes[format_.crc_offset] ^= 0x01;
      } else {
        bytes.resize(bytes.size() / 2);  // no CRC to break: a frame cut short instead
      }
    }
    out.insert(out.end(), bytes.begin(), bytes.end());
  }
  write_locked(out);
}

void SerialGyroPeer::send_raw(std::span<const std::uint8_t> bytes) {
  std::lock_guard lock(mutex_);
  if (master_ >= 0) write_locked(bytes);
}

void SerialGyroPeer::write_locked(std::span<const std::uint8_t> bytes) {
  std::size_t done = 0;
  while (done < bytes.size()) {
    const auto n = ::write(master_, bytes.data() + done, bytes.size() - done);
    if (n > 0) {
      done += static_cast<std::size_t>(n);
      continue;
    }
    if (n < 0 && errno == EINTR) continue;
    // Full (no reader, or a slow one), or the reader side not open: the rest is lost on the line.
    dropped_ += bytes.size() - done;
    return;
  }
}

std::uint64_t SerialGyroPeer::dropped() const {
  std::lock_guard lock(mutex_);
  return dropped_;
}

void SerialGyroPeer::close() {
  std::lock_guard lock(mutex_);
  if (master_ >= 0) ::close(master_);
  master_ = -1;
  if (!link_.empty()) ::unlink(link_.c_str());
  link_.clear();
}

}  // namespace fogbench::mock
