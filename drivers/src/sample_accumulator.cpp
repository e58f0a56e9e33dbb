// Per-unit averaging of gyro frames into samples and the accounting of unusable frames.
#include "fogbench/drivers/sample_accumulator.hpp"

#include <algorithm>
#include <limits>

#include "fogbench/drivers/can_frame.hpp"

namespace fogbench::drivers {

double GyroChannelConfig::mean_counts_to_rate_dph(double mean_counts) const noexcept {
  if (mode == GyroMode::rate) return mean_counts * scale_dph_per_count;
  return mean_counts * scale_deg_per_count * frame_rate_hz * 3600.0;
}

SampleAccumulator::SampleAccumulator(GyroChannelConfig config, std::uint8_t axis) noexcept
    : config_(config), axis_(axis), frame_id_(config.axis_id(axis)) {
  current_.node_id = config_.node_id;
  current_.axis = axis_;
}

void SampleAccumulator::add(const ::can_frame& frame) noexcept {
  if ((frame.can_id & (CAN_EFF_FLAG | CAN_RTR_FLAG | CAN_ERR_FLAG)) != 0 ||
      (frame.can_id & CAN_SFF_MASK) != frame_id_) {
    ++current_.frames_foreign;
    return;
  }
  const auto decoded = can::decode(frame);
  if (!decoded) {
    ++current_.frames_corrupt;
    ++corrupt_since_good_;
    return;
  }
  ++current_.frames;
  current_.status_or |= decoded->status;
  if (have_sequence_) {
    const auto step = static_cast<std::uint8_t>(decoded->sequence - last_sequence_);
    if (step == 0) {
      // A repeat (a retransmission or a stuck counter) carries no new measurement.
      ++current_.frames_repeated;
      return;
    }
    const std::uint32_t gap = static_cast<std::uint8_t>(step - 1);
    current_.frames_lost += gap - std::min(gap, corrupt_since_good_);
  }
  // A power-on as the gyro tells it: only a start-up sets `warming_up`, and its counter starts
  // at 0. Late or bunched frames of a running gyro carry neither, whatever the reader's timing.
  const bool warming_up = (decoded->status & can::status::warming_up) != 0;
  if (warming_up) {
    const bool starts = have_sequence_ ? !last_warming_up_ || (decoded->sequence == 0 && last_sequence_ != 255)
                                       : decoded->sequence == 0;
    if (starts) ++current_.starts;
  }
  last_warming_up_ = warming_up;
  have_sequence_ = true;
  last_sequence_ = decoded->sequence;
  corrupt_since_good_ = 0;
  if (decoded->status & can::status::valid) {
    current_.sum_counts += decoded->counts;
    ++current_.frames_used;
    if (decoded->counts == std::numeric_limits<std::int32_t>::max() ||
        decoded->counts == std::numeric_limits<std::int32_t>::min())
      ++current_.frames_saturated;
  }
}

GyroSample SampleAccumulator::close() noexcept {
  GyroSample out = current_;
  if (out.frames_used > 0) {
    const double mean = static_cast<double>(out.sum_counts) / out.frames_used;
    out.rate_dph = config_.mean_counts_to_rate_dph(mean);
  }
  current_ = GyroSample{};
  current_.node_id = config_.node_id;
  current_.axis = axis_;
  return out;
}

}  // namespace fogbench::drivers
