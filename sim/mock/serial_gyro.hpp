// The mock bench's serial gyro: one unit's gyro frames written as a binary serial frame
// (drivers' serial_frame.hpp, the layout a configuration gives) to a pseudo-terminal, whose slave
// a driver opens as its serial device through a symlink at a chosen path. Fed the CAN frames the
// bench clock makes, so the serial stream has the same rates, gaps and corrupt frames: a lost
// CAN frame is not written, a corrupt one is written with its CRC broken.
#pragma once

#include <linux/can.h>

#include <cstdint>
#include <expected>
#include <mutex>
#include <span>
#include <string>
#include <vector>

#include "fogbench/drivers/serial_frame.hpp"

namespace fogbench::mock {

class SerialGyroPeer {
 public:
  SerialGyroPeer() = default;
  ~SerialGyroPeer() { close(); }
  SerialGyroPeer(const SerialGyroPeer&) = delete;
  SerialGyroPeer& operator=(const SerialGyroPeer&) = delete;

  // Opens a pty and links `link_path` to its slave (a stale link is replaced). Frames of
  // `node_id` are served; `scale_dph_per_count` turns their counts into deg/h.
  std::expected<void, std::string> open(const std::string& link_path, drivers::serial::FrameFormat format,
                                        std::uint16_t node_id, double scale_dph_per_count);
  // Writes the frames of the node without blocking; what the pty cannot take is dropped (the
  // reader sees the gap in the counter).
  void send(std::span<const ::can_frame> frames);
  // Bytes written as they are, for faults (garbage between frames).
  void send_raw(std::span<const std::uint8_t> bytes);
  std::uint64_t dropped() const;
  std::string slave() const { return slave_; }
  void close();

 private:
  void write_locked(std::span<const std::uint8_t> bytes);

  mutable std::mutex mutex_;
  int master_ = -1;
  std::string link_;
  std::string slave_;
  drivers::serial::FrameFormat format_;
  std::uint16_t node_id_ = 0;
  double scale_dph_per_count_ = 0;
  bool have_sequence_ = false;
  std::uint8_t last_can_sequence_ = 0;
  std::uint32_t sequence_ = 0;
  std::uint64_t dropped_ = 0;
};

}  // namespace fogbench::mock
