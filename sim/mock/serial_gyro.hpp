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
#include "faults.hpp"

namespace fogbench::mock {

// What a UART reading 8N1 at `rx_baud` delivers from bytes sent 8N1 at `tx_baud`, the line idle
// (high) before and after them: the sender's waveform (a start bit 0, eight data bits LSB first,
// a stop bit 1 per byte) sampled the way a receiver samples it: it waits for a falling edge, takes
// the data bits at the middle of each of its own bit times (1.5, 2.5, ... 8.5 bit times after
// the edge) and the stop bit at 9.5, then waits for the next edge. A byte whose stop bit reads 0
// (a framing error) is delivered as sampled, as Linux does without INPCK. Equal rates give the
// bytes back. Exact: times are integers in units of 1 / (2 tx_baud rx_baud) s.
std::vector<std::uint8_t> uart_resample(std::span<const std::uint8_t> bytes, int tx_baud, int rx_baud);

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
  // Bytes written as they are.
  void send_raw(std::span<const std::uint8_t> bytes);
  // The line's faults from now on (FaultState::serial, switched by the fault commands
  // serial_garbage, serial_cut, serial_bad_crc, serial_baud). Each fraction picks every
  // 1/fraction-th frame (an accumulator, no random draw), so a test knows how many.
  void set_faults(const SerialLineFaults& faults);
  std::uint64_t dropped() const;
  std::string slave() const { return slave_; }
  void close();

 private:
  void write_locked(std::span<const std::uint8_t> bytes);
  static bool due(double& accumulator, double fraction) noexcept;

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
  SerialLineFaults faults_;
  double garbage_due_ = 0, cut_due_ = 0, bad_crc_due_ = 0;  // the fractions' accumulators
};

}  // namespace fogbench::mock
