// See bench_clock.hpp.
#include "bench_clock.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>

#include "bench.hpp"
#include "fogbench/drivers/can_frame.hpp"

namespace fogbench::mock {

namespace {
// Below this the clock does not sleep: frames due within it go out in one batch, so a high
// frame rate times a high time scale costs one wake-up per millisecond, not one per frame.
constexpr auto min_sleep = std::chrono::milliseconds(1);
// Air within this of the setpoint shows the status bit at_setpoint, degC.
constexpr double at_setpoint_band_c = 0.5;
// The physics accepts setpoints in this range; a client's wilder value is clamped, degC.
constexpr double min_setpoint_c = -100.0, max_setpoint_c = 250.0;
}  // namespace

std::expected<void, std::string> BenchClock::init() {
  auto w = sim::World::create(cfg_.sim);
  if (!w) return std::unexpected(w.error());
  world_.emplace(std::move(*w));
  axis_streams_.resize(cfg_.units.size());
  axis_rngs_.resize(cfg_.units.size());
  for (std::size_t u = 0; u < cfg_.units.size(); ++u) {
    const auto& g = cfg_.sim.units[u].gyro;
    const Warmup wu = u < cfg_.warmup.size() ? cfg_.warmup[u] : Warmup{};
    if (!(wu.tau_s > 0)) return std::unexpected("unit " + cfg_.units[u].serial + ": warm-up tau_s must be positive");
    const StreamParams params{.frame_rate_hz = cfg_.units[u].frame_rate_hz,
                              .counts_per_dph = cfg_.units[u].counts_per_dph(),
                              .ar = g.ar,
                              .sigma_a_dph = g.sigma_a_dph,
                              .outlier_rate_per_s = g.outlier_rate_per_s,
                              .outlier_dph = g.outlier_dph,
                              .white_dph = cfg_.frame_noise_dph,
                              .warmup_dph = wu.dph,
                              .warmup_tau_s = wu.tau_s,
                              .startup_flag_s = cfg_.startup_flag ? 1.0 : 0.0};
    streams_.emplace_back(params);
    for (std::uint8_t k = 1; k < cfg_.units[u].gyro.axes; ++k) {
      axis_streams_[u].emplace_back(params);
      axis_rngs_[u].emplace_back(cfg_.sim.seed ^ (0x2545F4914F6CDD1Dull * (4 * u + k + 1)));
    }
  }
  return {};
}

void BenchClock::start() { thread_ = std::thread([this] { loop(); }); }

void BenchClock::stop() {
  stopping_ = true;
  cv_.notify_all();
  done_cv_.notify_all();
  if (thread_.joinable()) thread_.join();
}

// Called on the server loop: the clock thread steps, and the reply waits for it, so a client
// that reads its reply finds every frame of those seconds already in its CAN socket and the
// registers showing their end. Modbus requests wait meanwhile (microseconds per second).
std::expected<double, std::string> BenchClock::advance(std::int64_t seconds) {
  if (!cfg_.paced) return std::unexpected(std::string("the bench keeps its own clock (start it with --paced)"));
  std::unique_lock lock(cv_mutex_);
  paced_target_ = paced_done_ + seconds;
  const std::int64_t want = paced_target_;
  cv_.notify_all();
  if (!done_cv_.wait_for(lock, std::chrono::seconds(10), [&] { return paced_done_ >= want || stopping_.load(); }))
    return std::unexpected("the clock did not reach " + std::to_string(want) + " s within 10 s");
  if (paced_done_ < want) return std::unexpected(std::string("stopping"));
  return static_cast<double>(paced_done_);
}

BenchClock::Clock::time_point BenchClock::wall(Clock::time_point t0, double sim_s) const {
  return t0 + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(sim_s / cfg_.time_scale));
}

void BenchClock::loop() {
  const auto t0 = Clock::now();
  const std::size_t nu = cfg_.units.size();
  Batch b;
  b.frames.resize(nu);
  b.axis_frames.resize(nu);
  for (std::size_t u = 0; u < nu; ++u) b.axis_frames[u].resize(axis_streams_[u].size());
  b.next.assign(nu, 0);
  std::mt19937_64 rng(cfg_.sim.seed ^ 0x9E3779B97F4A7C15ull);  // its own stream: the world's is untouched
  std::vector<::can_frame> out;
  std::int64_t next_step = 0;
  double last_setpoint_c = cfg_.sim.start_c;
  auto last_behind_warning = Clock::time_point{};
  constexpr auto all = Clock::time_point::max();

  while (!stopping_) {
    auto now = Clock::now();
    auto step_due = [&] {
      if (!cfg_.paced) return wall(t0, static_cast<double>(next_step)) <= now;
      std::lock_guard lock(cv_mutex_);
      return next_step < paced_target_;
    };
    while (step_due() && !stopping_) {
      emit(b, all, t0, rng, out);  // the rest of the second, now due
      step(b, next_step, last_setpoint_c, rng);
      ++next_step;
      if (cfg_.duration_s > 0 && static_cast<double>(next_step) >= cfg_.duration_s) {
        emit(b, all, t0, rng, out);
        on_end_();
        stopping_ = true;
        break;
      }
      if (!cfg_.paced && now - wall(t0, static_cast<double>(next_step)) > std::chrono::seconds(1) &&
          now - last_behind_warning > std::chrono::seconds(5)) {
        last_behind_warning = now;
        spdlog::warn("the physics runs {:.1f} s (wall) behind the scaled clock: lower --time-scale",
                     std::chrono::duration<double>(now - wall(t0, static_cast<double>(next_step))).count());
      }
    }
    if (stopping_) break;
    if (cfg_.paced) {
      // Every frame of the seconds stepped goes out before the client hears they are done;
      // then nothing moves until it asks for more.
      emit(b, all, t0, rng, out);
      std::unique_lock lock(cv_mutex_);
      paced_done_ = next_step;
      done_cv_.notify_all();
      // Bounded: `stopping_` is set without cv_mutex_, so a wake-up could slip past the wait.
      cv_.wait_for(lock, std::chrono::milliseconds(100), [&] { return stopping_.load() || paced_target_ > next_step; });
      continue;
    }
    emit(b, now, t0, rng, out);
    auto wake = wall(t0, static_cast<double>(next_step));
    for (std::size_t u = 0; u < nu; ++u) {
      if (b.next[u] < b.frames[u].size()) {
        wake = std::min(wake, wall(t0, static_cast<double>(b.second) + static_cast<double>(b.next[u]) / cfg_.units[u].frame_rate_hz));
      }
    }
    wake = std::max(wake, now + min_sleep);
    std::unique_lock lock(cv_mutex_);
    cv_.wait_until(lock, wake, [&] { return stopping_.load(); });
  }
}

// Advances the world one second and shows its state in the registers.
void BenchClock::step(Batch& b, std::int64_t second, double& last_setpoint_c, std::mt19937_64& rng) {
  double setpoint_c = last_setpoint_c;
  bool running = true;
  std::vector<UnitFaults> unit_faults;
  {
    std::lock_guard lock(shared_.mutex);
    setpoint_c = shared_.chamber->setpoint_c(last_setpoint_c);
    running = shared_.chamber->running();
    unit_faults = shared_.faults.units;
  }
  if (setpoint_c != last_setpoint_c) spdlog::debug("setpoint {} degC", setpoint_c);
  last_setpoint_c = setpoint_c;
  const double commanded = std::clamp(setpoint_c, min_setpoint_c, max_setpoint_c);
  // A stopped chamber no longer controls: its air drifts back to the room's temperature.
  world_->step(running ? commanded : cfg_.sim.start_c);
  // The rate table's rate at the second's start (without its ripple, whose mean over a second
  // is about 0): every unit sits on the table, its axis 0 on the table's axis. The table moves
  // with the bench's time: free-running, wall time times the scale, this second's; paced, the
  // simulated seconds advance asks for (its commands are answered at that time too, bench.cpp).
  double table_dps = 0.0;
  {
    std::lock_guard lock(shared_.mutex);
    if (shared_.rate_table) {
      shared_.rate_table->advance_to(static_cast<double>(second));
      table_dps = shared_.rate_table->smooth_rate_dps();
    }
  }
  const double pv_c = world_->chamber_reading_c();
  b.second = second;
  std::vector<double> gyro_dph(cfg_.units.size());
  for (std::size_t u = 0; u < cfg_.units.size(); ++u) {
    const auto& f = unit_faults[u];
    const double spike = static_cast<double>(second) < f.spike_until_s ? f.spike_dph : 0.0;
    // The world's deterministic drift for the second; the gyro's noise is made at the frame
    // rate by its stream (the world's own 1 s noise is left out), so the reader's 1 s means
    // carry the specified AR noise whatever their phase.
    const auto s = world_->sample(u);
    const double turn_dph =
        table_dps == 0.0 ? 0.0 : 3600.0 * sim::indicated_rate_dps(cfg_.sf_truth, table_dps, world_->true_t1_c(u), 0.0);
    streams_[u].second(second, s.gyro_dph - s.noise_dph + spike + turn_dph, {f.power_off_from_s, f.power_on_at_s}, rng,
                       b.frames[u]);
    gyro_dph[u] = streams_[u].last_mean_dph();
    // The other axes: the same housing's drift (without x's own; with coils per axis, read on
    // the axis's own coil) plus each axis's own bias, its own drift (--axis-effect) and its
    // own noise.
    for (std::size_t k = 0; k < axis_streams_[u].size(); ++k) {
      axis_streams_[u][k].second(second,
                                 s.gyro_dph - s.noise_dph - world_->axis_drift_dph(u, 0) + spike + cfg_.units[u].axis_bias_dph[k + 1] +
                                     world_->axis_drift_dph(u, k + 1),
                                 {f.power_off_from_s, f.power_on_at_s}, axis_rngs_[u][k], b.axis_frames[u][k]);
    }
    b.next[u] = 0;
  }
  const double air_c = world_->air_c();
  std::lock_guard lock(shared_.mutex);
  auto& faults = shared_.faults;
  shared_.chamber->show({.process_value_c = pv_c,
                         .freeze_pv = faults.freeze_pv,
                         .heating = running && commanded - air_c > at_setpoint_band_c,
                         .cooling = running && air_c - commanded > at_setpoint_band_c,
                         .at_setpoint = running && std::abs(commanded - air_c) <= at_setpoint_band_c,
                         .alarm = faults.alarm});
  auto& snap = shared_.snap;
  snap.time_s = world_->time_s();
  snap.setpoint_c = setpoint_c;
  snap.running = running;
  snap.air_c = air_c;
  if (!faults.freeze_pv) snap.pv_c = pv_c;
  for (std::size_t u = 0; u < cfg_.units.size(); ++u) {
    const auto s = world_->sample(u);
    shared_.thermistors->show(u, 1, s.t1_c, faults.units[u].open_t1);
    shared_.thermistors->show(u, 2, s.t2_c, faults.units[u].open_t2);
    if (world_->has_axis_coils(u))
      for (std::size_t k = 1; k < 3; ++k) {
        shared_.thermistors->show(u, 1, s.axis_t1_c[k - 1], false, k);
        shared_.thermistors->show(u, 2, s.axis_t2_c[k - 1], false, k);
      }
    auto& us = snap.units[u];
    us.t1_c = s.t1_c;
    us.t2_c = s.t2_c;
    us.true_t1_c = world_->true_t1_c(u);
    us.true_t2_c = world_->true_t2_c(u);
    us.gyro_dph = gyro_dph[u];
    us.powered = streams_[u].powered();
    us.powered_on_at_s = streams_[u].powered_on_at_s();
    us.axis_gyro_dph.clear();
    for (const auto& a : axis_streams_[u]) us.axis_gyro_dph.push_back(a.last_mean_dph());
  }
}

// A lost frame still uses its sequence number: the reader sees the gap.
void BenchClock::emit(Batch& b, Clock::time_point until, Clock::time_point t0, std::mt19937_64& rng,
                      std::vector<::can_frame>& out) {
  out.clear();
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  auto due = [&](std::size_t u, std::size_t j) {
    return wall(t0, static_cast<double>(b.second) + static_cast<double>(j) / cfg_.units[u].frame_rate_hz);
  };
  {
    std::lock_guard lock(shared_.mutex);
    for (std::size_t u = 0; u < b.frames.size(); ++u) {
      auto& f = shared_.faults.units[u];
      auto& st = shared_.snap.units[u];
      while (b.next[u] < b.frames[u].size() && (until == Clock::time_point::max() || due(u, b.next[u]) <= until)) {
        const std::size_t j = b.next[u];
        const StreamFrame slot = b.frames[u][b.next[u]++];
        // Axes 1 and 2 of the slot, after axis 0 (the order the bus arbitrates them in): lost and
        // corrupted at the unit's fractions by their own draws; a burst loss is axis 0's alone.
        auto other_axes = [&] {
          for (std::size_t k = 0; k < b.axis_frames[u].size(); ++k) {
            const StreamFrame a = b.axis_frames[u][k][j];
            if (!a.powered || f.silent_axis[k + 1]) continue;  // no power or silenced: no frame
            auto& arng = axis_rngs_[u][k];
            ++st.axes_frames_sent;
            if (f.lose_fraction > 0 && uniform(arng) < f.lose_fraction) {
              ++st.axes_frames_lost;
              continue;
            }
            const std::uint8_t astatus = drivers::can::status::valid | (a.warming_up ? drivers::can::status::warming_up : 0);
            const auto axis = static_cast<std::uint8_t>(k + 1);
            ::can_frame frame = drivers::can::encode({cfg_.units[u].gyro.axis_id(axis), a.counts, a.sequence, astatus});
            if (f.corrupt_fraction > 0 && uniform(arng) < f.corrupt_fraction) {
              const auto bit = std::uniform_int_distribution<int>(0, 55)(arng);
              frame.data[bit / 8] ^= static_cast<std::uint8_t>(1u << (bit % 8));
              ++st.axes_frames_corrupted;
            }
            out.push_back(frame);
          }
        };
        if (!slot.powered) continue;  // no power, no frame
        if (f.silent_axis[0]) {       // axis x silenced: y and z still speak
          other_axes();
          continue;
        }
        ++st.frames_sent;
        if (f.lose_burst > 0 || (f.lose_fraction > 0 && uniform(rng) < f.lose_fraction)) {
          if (f.lose_burst > 0) --f.lose_burst;
          ++st.frames_lost;
          other_axes();
          continue;
        }
        const std::uint8_t status = drivers::can::status::valid | (slot.warming_up ? drivers::can::status::warming_up : 0);
        ::can_frame frame = drivers::can::encode({cfg_.units[u].gyro.node_id, slot.counts, slot.sequence, status});
        if (f.corrupt_fraction > 0 && uniform(rng) < f.corrupt_fraction) {
          // One bit of bytes 0..6: CRC-8 detects every single-bit error.
          const auto bit = std::uniform_int_distribution<int>(0, 55)(rng);
          frame.data[bit / 8] ^= static_cast<std::uint8_t>(1u << (bit % 8));
          ++st.frames_corrupted;
        }
        out.push_back(frame);
        other_axes();
      }
    }
  }
  can_.send(out);
}

}  // namespace fogbench::mock
