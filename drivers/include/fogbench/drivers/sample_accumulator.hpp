// Averaging of one gyro's CAN frames into 1 s samples, with the frame accounting a drift run needs
// (lost, corrupt, foreign, repeated). Pure: the caller feeds frames and decides when a sample ends.
#pragma once

#include <linux/can.h>

#include <cstdint>
#include <optional>

namespace fogbench::drivers {

// What the 32-bit counts of a frame mean.
enum class GyroMode {
  rate,       // an angular rate: rate_dph = counts * scale_dph_per_count
  increment,  // the angle turned since the previous frame: deg = counts * scale_deg_per_count
};

struct GyroChannelConfig {
  std::uint16_t node_id = 0;       // standard CAN id of the unit's frames, 1..2047
  GyroMode mode = GyroMode::rate;
  double scale_dph_per_count = 0;  // rate mode
  double scale_deg_per_count = 0;  // increment mode
  double frame_rate_hz = 0;        // increment mode: the gyro's nominal output rate
  // Its frames carry the status bit `warming_up` after a power-on (docs/can-frames.md
  // "Power-on"), the evidence a power-on is known by. False ("startup_flag": false): a gyro kind
  // without it, whose power-on cannot be known from its frames (its runs say so in a note).
  bool startup_flag = true;
  // 1, or 3 for a three-axis unit: its axis k (0, 1, 2 = x, y, z) sends on the standard id
  // node_id + k, each axis with its own sequence counter (docs/drivers.md "Three-axis units").
  std::uint8_t axes = 1;

  // The CAN id of axis k's frames.
  std::uint16_t axis_id(std::uint8_t axis) const noexcept {
    return static_cast<std::uint16_t>(node_id + axis);
  }

  // The mean of the counts of a sample's frames as a rate in deg/h. In increment mode the mean
  // increment per frame times the nominal frame rate: a lost frame then leaves the rate unbiased,
  // where summing the increments over the second would read low by one frame's worth.
  double mean_counts_to_rate_dph(double mean_counts) const noexcept;
};

// One closed sample. frames + frames_corrupt + frames_lost is the number of frames the gyro sent
// in the interval (as far as the sequence counter can tell, i.e. fewer than 256 missing in a row).
struct GyroSample {
  std::uint16_t node_id = 0;
  std::optional<double> rate_dph;    // mean over the frames used; empty when none was usable
  std::uint32_t frames = 0;          // well-formed frames with this id, usable or not
  std::uint32_t frames_used = 0;     // averaged: `valid` status bit set and not a repeat
  std::uint32_t frames_lost = 0;     // sequence gaps not accounted for by corrupt frames
  std::uint32_t frames_corrupt = 0;  // this id, but wrong DLC or bad CRC
  std::uint32_t frames_foreign = 0;  // another id, or not a standard data frame
  std::uint32_t frames_repeated = 0; // same sequence number as the frame before: not averaged
  std::uint8_t status_or = 0;        // OR of the status bytes of the well-formed frames
  // Frames that begin a power-on, by the gyro's own evidence (docs/can-frames.md "Power-on"):
  // `warming_up` set where the frame before had it clear, or the counter back at 0 in
  // `warming_up` without continuing from 255; the first frame ever seen counts only at sequence 0.
  // A late reader, a paused one or lost frames of a running gyro never make one.
  std::uint32_t starts = 0;
  std::int64_t sum_counts = 0;       // of the frames used (exact; the mean is this / frames_used)
  // Frames used whose counts are at the int32 limit (INT32_MIN or INT32_MAX): a gyro whose rate
  // is beyond what its scale can carry sends the limit, so the mean is a clipped rate.
  std::uint32_t frames_saturated = 0;
  // The axis this sample is of (0 for a one-axis unit); node_id stays the unit's (base) id, the
  // frames' id is node_id + axis.
  std::uint8_t axis = 0;
};

class SampleAccumulator {
 public:
  // Accumulates axis `axis` of the unit (0..config.axes-1): the frames of id
  // config.axis_id(axis), all others counted foreign.
  explicit SampleAccumulator(GyroChannelConfig config, std::uint8_t axis = 0) noexcept;

  // Accounts one frame. Never fails: a frame that cannot be used is counted, not returned.
  void add(const ::can_frame& frame) noexcept;

  // Returns the sample accumulated since the previous close and starts the next one. The
  // sequence tracking carries over, so a frame lost across the boundary is counted once.
  GyroSample close() noexcept;

  const GyroChannelConfig& config() const noexcept { return config_; }
  std::uint8_t axis() const noexcept { return axis_; }

 private:
  GyroChannelConfig config_;
  std::uint8_t axis_ = 0;
  std::uint16_t frame_id_ = 0;  // config_.axis_id(axis_)
  GyroSample current_;
  bool have_sequence_ = false;
  std::uint8_t last_sequence_ = 0;
  bool last_warming_up_ = false;  // the last well-formed, non-repeated frame was warming up
  std::uint32_t corrupt_since_good_ = 0;  // explains sequence gaps: a corrupt frame is not lost
};

}  // namespace fogbench::drivers
