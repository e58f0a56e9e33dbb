// See serial_gyro.hpp.
#include "serial_gyro.hpp"

#include <fcntl.h>
#include <stdlib.h>
#include <termios.h>
#include <unistd.h>

#include <algorithm>
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
    const bool has_crc = format_.crc != drivers::serial::CrcKind::none;
    if (!decoded) {
      if (has_crc) {
        bytes[format_.crc_offset] ^= 0x01;
      } else {
        bytes.resize(bytes.size() / 2);  // no CRC to break: a frame cut short instead
      }
    } else if (has_crc && due(bad_crc_due_, faults_.bad_crc_fraction)) {
      bytes[format_.crc_offset] ^= 0x01;
    } else if (due(cut_due_, faults_.cut_fraction)) {
      bytes.resize(bytes.size() / 2);
    }
    std::vector<std::uint8_t> chunk;
    if (due(garbage_due_, faults_.garbage_fraction)) {
      // Bytes that never begin the sync word: one run of garbage, whatever follows.
      std::uint8_t b = 0x11;
      for (int i = 0; i < faults_.garbage_bytes; ++i) {
        while (b == format_.sync.front()) b = static_cast<std::uint8_t>(b + 0x11);
        chunk.push_back(b);
        b = static_cast<std::uint8_t>(b + 0x11);
      }
    }
    chunk.insert(chunk.end(), bytes.begin(), bytes.end());
    // At another baud rate each frame is mis-sampled on its own: the gyro's frames are apart in
    // time (a 36-byte frame takes 0.4 ms of a 1 ms period at 921600 baud), the line idle between.
    if (faults_.baud > 0 && faults_.baud != faults_.line_baud) chunk = uart_resample(chunk, faults_.baud, faults_.line_baud);
    out.insert(out.end(), chunk.begin(), chunk.end());
  }
  write_locked(out);
}

void SerialGyroPeer::set_faults(const SerialLineFaults& faults) {
  std::lock_guard lock(mutex_);
  faults_ = faults;
}

bool SerialGyroPeer::due(double& accumulator, double fraction) noexcept {
  if (!(fraction > 0)) return false;
  accumulator += fraction;
  if (accumulator < 1.0 - 1e-9) return false;
  accumulator -= 1.0;
  return true;
}

std::vector<std::uint8_t> uart_resample(std::span<const std::uint8_t> bytes, int tx_baud, int rx_baud) {
  // Time unit 1 / (2 tx rx) s: a sent bit lasts 2 rx units, a received bit 2 tx, half of one tx.
  const std::int64_t tx_bit = 2 * static_cast<std::int64_t>(rx_baud);
  const std::int64_t rx_half = tx_baud;
  const std::int64_t bits = 10 * static_cast<std::int64_t>(bytes.size());
  const auto bit = [&](std::int64_t j) -> int {  // the sent level of bit slot j (idle outside)
    if (j < 0 || j >= bits) return 1;
    const auto pos = j % 10;
    if (pos == 0) return 0;
    if (pos == 9) return 1;
    return (bytes[static_cast<std::size_t>(j / 10)] >> (pos - 1)) & 1;
  };
  const auto level = [&](std::int64_t t) { return bit(t / tx_bit); };
  std::vector<std::uint8_t> out;
  std::int64_t ready = 0;  // the receiver looks for a start bit from here
  for (std::int64_t j = 0; j < bits;) {
    // The next falling edge at or after `ready`: a slot boundary from 1 to 0.
    j = std::max(j, (ready + tx_bit - 1) / tx_bit);
    while (j < bits && !(bit(j) == 0 && bit(j - 1) == 1)) ++j;
    if (j >= bits) break;
    const std::int64_t edge = j * tx_bit;
    int byte = 0;
    for (int i = 0; i < 8; ++i) byte |= level(edge + (3 + 2 * i) * rx_half) << i;
    out.push_back(static_cast<std::uint8_t>(byte));
    ready = edge + 19 * rx_half;  // the stop bit's sample
    ++j;
  }
  return out;
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
