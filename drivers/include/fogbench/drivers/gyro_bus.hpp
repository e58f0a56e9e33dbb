// The gyros of every unit under test on one CAN bus: a transport, the user-space id filter, and
// one SampleAccumulator per unit. The daemon waits on fd(), calls read_frames() when it is
// readable, and close_samples() once per sample period (1 s).
#pragma once

#include <linux/can.h>

#include <array>
#include <cstdint>
#include <memory>
#include <vector>

#include "fogbench/drivers/can_transport.hpp"
#include "fogbench/drivers/config.hpp"
#include "fogbench/drivers/error.hpp"
#include "fogbench/drivers/sample_accumulator.hpp"

namespace fogbench::drivers {

struct BusSample {
  std::vector<GyroSample> units;     // in the order of the unit configs; axis 0 of each unit
  // Per unit (same order), the samples of its axes 1..axes-1: empty for a one-axis unit, axes
  // 1 and 2 (y, z) for a three-axis one. Every axis has its own sequence tracking and counts.
  std::vector<std::vector<GyroSample>> extra_axes;
  std::uint32_t frames_foreign = 0;  // ids of no unit, extended, remote or error frames
  std::uint64_t malformed_total = 0; // transport-level: datagrams or log lines not a frame
};

class GyroBus {
 public:
  // Takes an open transport (tests and benchmarks inject one). The ids of all units' axes
  // (node_id .. node_id + axes - 1) must be distinct and 1..2047, and axes 1 or 3
  // (parse_drivers_config guarantees it; asserted here).
  GyroBus(std::unique_ptr<CanTransport> transport, std::vector<GyroChannelConfig> units);

  // Opens the configured transport for these units; with `config.lines`, each unit that has a
  // serial line of its own is read there and the others on `config.transport`, all through one
  // combined transport (combine_transports).
  static Result<GyroBus> open(const GyroBusConfig& config, std::vector<GyroChannelConfig> units,
                              MonotonicClock clock = {});

  int fd() const noexcept { return transport_->fd(); }

  // Replaces `frames` with the frames available now (non-blocking) and routes each to its unit.
  // The frames are handed back so the caller may record them raw. Errors are the transport's:
  // connection (reopen() later) or end_of_stream (a replay ended).
  Result<std::size_t> read_frames(std::vector<::can_frame>& frames);

  // The single decode/filter/average path every transport feeds.
  void route(const ::can_frame& frame) noexcept;

  // Closes the current sample of every unit and starts the next.
  BusSample close_samples();

  // Reopens the transport after a connection error, keeping the accumulators (and so the
  // sequence tracking: the frames missed meanwhile are counted as lost).
  Result<void> reopen(const GyroBusConfig& config, MonotonicClock clock = {});

  // The transport's news about its stream since the last call (CanTransport::take_events: a
  // serial line's garbage, CRC errors, cut frames, wrong-baud silence), each naming the device.
  std::vector<CanTransport::Event> take_events() { return transport_->take_events(); }

  std::size_t unit_count() const noexcept { return units_.size(); }
  const CanTransport& transport() const noexcept { return *transport_; }

 private:
  std::unique_ptr<CanTransport> transport_;
  std::vector<GyroChannelConfig> units_;
  // Every axis of every unit, unit by unit: unit i's axis k at first_of_unit_[i] + k.
  std::vector<SampleAccumulator> accumulators_;
  std::vector<std::size_t> first_of_unit_;
  std::array<std::int16_t, CAN_SFF_MASK + 1> accumulator_of_id_;  // -1: no unit's axis has this id
  std::uint32_t foreign_ = 0;
};

}  // namespace fogbench::drivers
