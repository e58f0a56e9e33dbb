// The samples' reader thread of replicate_run (sample_stream.hpp).
#include "sample_stream.hpp"

#include "copy_binary.hpp"
#include "fogbench/storage/samples.hpp"

namespace fogbench::plant::detail {

SampleStream::SampleStream(storage::Store& bench, std::string bench_id, std::int64_t run_id, std::vector<int> units,
                           std::int64_t page, std::size_t depth)
    : bench_(bench), bench_id_(std::move(bench_id)), run_id_(run_id), units_(std::move(units)), page_(page),
      depth_(depth) {
  thread_ = std::thread([this] { run(); });
}

SampleStream::~SampleStream() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  cv_.notify_all();
  if (thread_.joinable()) thread_.join();
}

std::optional<SampleStream::Chunk> SampleStream::next() {
  std::unique_lock lock(mutex_);
  cv_.wait(lock, [this] { return !ready_.empty() || done_; });
  if (ready_.empty()) return std::nullopt;
  Chunk c = std::move(ready_.front());
  ready_.pop_front();
  cv_.notify_all();
  return c;
}

bool SampleStream::push(Chunk c) {
  std::unique_lock lock(mutex_);
  cv_.wait(lock, [this] { return ready_.size() < depth_ || stopping_; });
  if (stopping_) return false;
  ready_.push_back(std::move(c));
  cv_.notify_all();
  return true;
}

void SampleStream::run() {
  BinaryCopy out;
  out.reserve(static_cast<std::size_t>(page_) * 190);
  out.header();
  bool ok = true;
  for (std::size_t k = 0; ok && k < units_.size(); ++k) {
    const int unit = units_[k];
    for (std::int64_t offset = 0; ok; offset += page_) {
      auto rows = bench_.get_samples(run_id_, unit, offset, page_);
      if (!rows) {
        push(Chunk{{}, rows.error().message, 0});
        ok = false;
        break;
      }
      for (const auto& s : *rows) {
        out.row(23);
        out.text(bench_id_);
        out.int8(run_id_);
        out.int4(unit);
        for (double v : {s.t_s, s.wall_time, s.setpoint_c, s.chamber_c, s.gyro_dph}) out.float8(v);
        if (s.frames) out.int8(*s.frames);
        else out.null();
        out.float8(s.t1_c);
        out.float8(s.t2_c);
        out.int2(static_cast<std::int16_t>(s.phase));
        if (s.step) out.int4(*s.step);
        else out.null();
        out.int2(static_cast<std::int16_t>(s.flags));
        out.float8(s.since_power_on_s);
        for (double v : {s.compensated_dph, s.rate_in_dps, s.gyro_y_dph, s.gyro_z_dph}) out.float8(v);
        for (double v : {s.t1_y_c, s.t2_y_c, s.t1_z_c, s.t2_z_c}) out.float8(v);  // per-axis coils, degC
      }
      const auto n = static_cast<std::int64_t>(rows->size());
      const bool last_page = n < page_;
      if (last_page && k + 1 == units_.size()) out.trailer();
      if (!out.data().empty()) {
        Chunk c{std::move(out.data()), {}, n};
        out.clear();
        out.reserve(static_cast<std::size_t>(page_) * 190);
        if (!push(std::move(c))) ok = false;
      }
      if (last_page) break;
    }
  }
  if (ok && units_.empty()) {
    out.trailer();
    push(Chunk{std::move(out.data()), {}, 0});
  }
  std::lock_guard lock(mutex_);
  done_ = true;
  cv_.notify_all();
}

}  // namespace fogbench::plant::detail
