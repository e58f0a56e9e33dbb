// The mock bench's clock: a thread that steps the physics (sim::World) one simulated second at a
// time, K times faster than real time or, paced, only as far as a client asks (advance), shows
// each second's state in the served registers and sends each gyro's CAN frames at its frame
// rate, with the losses and corruption the faults ask for.
#pragma once

#include <linux/can.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <expected>
#include <functional>
#include <mutex>
#include <optional>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "can_bus.hpp"
#include "fogbench/sim/sim.hpp"
#include "frames.hpp"
#include "shared_state.hpp"

namespace fogbench::mock {

struct BenchConfig;

class BenchClock {
 public:
  using Clock = std::chrono::steady_clock;

  // `on_end` is called (on the clock thread) when the configured duration is reached.
  BenchClock(const BenchConfig& cfg, SharedState& shared, CanBus& can, std::function<void()> on_end)
      : cfg_(cfg), shared_(shared), can_(can), on_end_(std::move(on_end)) {}
  ~BenchClock() { stop(); }
  BenchClock(const BenchClock&) = delete;
  BenchClock& operator=(const BenchClock&) = delete;

  // Builds the world and each unit's gyro stream from the configuration.
  std::expected<void, std::string> init();
  void start();
  void stop();  // joins the thread; idempotent

  // --paced: steps `seconds` further, returns the simulated time once every frame of them is
  // sent (an error after 10 s without progress, or when stopping).
  std::expected<double, std::string> advance(std::int64_t seconds);

 private:
  struct Batch {  // the frame slots of the current simulated second, per unit
    std::vector<std::vector<StreamFrame>> frames;
    // A three-axis unit's axes 1 and 2: axis_frames[u][k - 1], slot for slot with frames[u].
    std::vector<std::vector<std::vector<StreamFrame>>> axis_frames;
    std::vector<std::size_t> next;  // next slot to send (of every axis of the unit)
    std::int64_t second = -1;       // its start, simulated seconds
  };

  void loop();
  void step(Batch& b, std::int64_t second, double& last_setpoint_c, std::mt19937_64& rng);
  // Sends the frames of the current second due by `until` (wall clock).
  void emit(Batch& b, Clock::time_point until, Clock::time_point t0, std::mt19937_64& rng, std::vector<::can_frame>& out);
  Clock::time_point wall(Clock::time_point t0, double sim_s) const;

  const BenchConfig& cfg_;
  SharedState& shared_;
  CanBus& can_;
  std::function<void()> on_end_;
  std::optional<sim::World> world_;
  std::vector<GyroStream> streams_;  // each unit's gyro at its frame rate (axis 0)
  // A three-axis unit's axes 1 and 2: axis_streams_[u][k - 1], each with its own noise from its
  // own random stream (axis_rngs_, also its frame faults' draws), so axis 0 and every one-axis
  // unit draw exactly what they drew before axes existed.
  std::vector<std::vector<GyroStream>> axis_streams_;
  std::vector<std::vector<std::mt19937_64>> axis_rngs_;
  std::thread thread_;
  std::mutex cv_mutex_;
  std::condition_variable cv_;
  std::atomic<bool> stopping_{false};
  // --paced: the clock steps up to paced_target_ (seconds asked for by advance()) and reports
  // paced_done_ once every frame of them is sent; both under cv_mutex_.
  std::condition_variable done_cv_;
  std::int64_t paced_target_ = 0, paced_done_ = 0;
};

}  // namespace fogbench::mock
