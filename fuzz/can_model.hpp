// The frame accounting of docs/can-frames.md restated as a plain model, independent of
// SampleAccumulator's code: the CAN fuzz targets feed both the same frames and compare.
#pragma once

#include <linux/can.h>

#include <cstdint>

#include "common.hpp"
#include "fogbench/drivers/can_frame.hpp"
#include "fogbench/drivers/sample_accumulator.hpp"

namespace fogbench::fuzz {

class AccountingModel {
 public:
  explicit AccountingModel(std::uint16_t node_id) : node_id_(node_id) {}

  void add(const ::can_frame& f) {
    ++added_;
    const bool standard_data = (f.can_id & (CAN_EFF_FLAG | CAN_RTR_FLAG | CAN_ERR_FLAG)) == 0;
    if (!standard_data || (f.can_id & CAN_SFF_MASK) != node_id_) {
      ++foreign_;
      return;
    }
    const auto d = drivers::can::decode(f);
    if (!d) {
      ++corrupt_;
      ++corrupt_run_;
      return;
    }
    ++frames_;
    status_or_ |= d->status;
    if (have_seq_ && d->sequence == last_seq_) {  // a repeat carries no new measurement
      ++repeated_;
      return;
    }
    if (have_seq_) {
      const unsigned gap = static_cast<std::uint8_t>(d->sequence - last_seq_ - 1);
      lost_ += gap > corrupt_run_ ? gap - corrupt_run_ : 0;
    }
    have_seq_ = true;
    last_seq_ = d->sequence;
    corrupt_run_ = 0;
    if (d->status & drivers::can::status::valid) {
      ++used_;
      sum_ += d->counts;
    }
  }

  // Compares a closed sample with the model's and starts the next one.
  void check_close(const drivers::GyroSample& s) {
    FUZZ_CHECK(s.node_id == node_id_, "sample of node %u, accumulator of %u", s.node_id, node_id_);
    FUZZ_CHECK(s.frames + s.frames_corrupt + s.frames_foreign == added_,
               "%u frames added, %u + %u corrupt + %u foreign accounted", added_, s.frames,
               s.frames_corrupt, s.frames_foreign);
    FUZZ_CHECK(s.frames == frames_ && s.frames_corrupt == corrupt_ && s.frames_foreign == foreign_,
               "frames %u/%u corrupt %u/%u foreign %u/%u (accumulator/model)", s.frames, frames_,
               s.frames_corrupt, corrupt_, s.frames_foreign, foreign_);
    FUZZ_CHECK(s.frames_used == used_ && s.frames_repeated == repeated_ && s.frames_lost == lost_,
               "used %u/%u repeated %u/%u lost %u/%u (accumulator/model)", s.frames_used, used_,
               s.frames_repeated, repeated_, s.frames_lost, lost_);
    FUZZ_CHECK(s.status_or == status_or_ && s.sum_counts == sum_, "status or sum of counts differ");
    FUZZ_CHECK(s.rate_dph.has_value() == (used_ > 0), "a rate %s with %u frames used",
               s.rate_dph ? "given" : "missing", used_);
    added_ = frames_ = corrupt_ = foreign_ = used_ = repeated_ = lost_ = 0;
    status_or_ = 0;
    sum_ = 0;
  }

 private:
  std::uint16_t node_id_;
  std::uint32_t added_ = 0, frames_ = 0, corrupt_ = 0, foreign_ = 0, used_ = 0, repeated_ = 0, lost_ = 0;
  std::uint8_t status_or_ = 0;
  std::int64_t sum_ = 0;
  bool have_seq_ = false;
  std::uint8_t last_seq_ = 0;
  std::uint32_t corrupt_run_ = 0;  // corrupt frames since the last good one
};

}  // namespace fogbench::fuzz
