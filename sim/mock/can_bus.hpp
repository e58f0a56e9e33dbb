// The mock bench's CAN bus: an AF_UNIX SOCK_SEQPACKET socket that gyro readers connect to, one
// struct can_frame per datagram. The server loop accepts readers; the clock thread sends frames
// to all of them, never blocking: a reader whose socket is full misses frames (it sees the gap
// in the sequence counter). The list of readers is under the bus's own mutex.
#pragma once

#include <linux/can.h>

#include <chrono>
#include <cstdint>
#include <expected>
#include <mutex>
#include <span>
#include <string>
#include <vector>

namespace fogbench::mock {

class SerialGyroPeer;

class CanBus {
 public:
  CanBus() = default;
  ~CanBus() { close(); }
  CanBus(const CanBus&) = delete;
  CanBus& operator=(const CanBus&) = delete;

  // Listens at `path` (a stale socket file is replaced).
  std::expected<void, std::string> listen(const std::string& path);
  int fd() const noexcept { return fd_; }
  // Accepts one reader (server loop).
  void accept();
  // Sends the frames to every reader without blocking; a reader that left is closed (clock).
  void send(std::span<const ::can_frame> frames);
  std::size_t readers() const;
  std::uint64_t dropped() const;  // frames a slow reader's full socket could not take
  // Every frame sent is also handed to this serial gyro (serial_gyro.hpp); null: none. Set
  // before the clock starts.
  void tap(SerialGyroPeer* peer) noexcept { tap_ = peer; }
  // Closes the readers and the listener and removes the socket file.
  void close();

 private:
  void warn_slow_reader(std::size_t n);

  std::string path_;
  int fd_ = -1;
  mutable std::mutex mutex_;
  std::vector<int> readers_;
  std::uint64_t dropped_ = 0;
  SerialGyroPeer* tap_ = nullptr;
  std::chrono::steady_clock::time_point last_slow_warning_{};
};

}  // namespace fogbench::mock
