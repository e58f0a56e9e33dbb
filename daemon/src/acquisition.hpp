// The acquisition (issue 26): the devices and the one schedule that turns them into one
// TickInput per second. It is handed the devices through interfaces (a drivers::Chamber, a
// drivers::ThermistorSource, the gyro bus's opener, and for the mock bench's paced clock a
// PacedWorld), owns their worker threads and the schedule's timer on the loop, and hands each
// second to a TickSink (the station, through the server's wiring), which answers with the
// setpoint the chamber should hold. It knows nothing of sockets, sessions or the store.
//
// One schedule, two clocks. Second k is closed at t0 + k periods on the loop: the gyro bus's
// sample since the last tick, and the latest readings of the chamber and the thermistor module,
// become one TickInput. What a clock decides is how a second's readings are made and what a
// late loop does:
//   - the real clock: the devices are polled half a period before each tick (the chamber on the
//     device worker, the module on its own, so a stalled one does not make the other late); a
//     tick never waits: a part that did not arrive stands in once from the period before, then
//     is missing (the tick says `late`); a loop far behind skips ahead, the skipped seconds
//     stored as not read;
//   - the paced clock (config "sim_clock", fogbench-sim --paced): after each tick one job on the
//     device worker writes the commanded setpoint, asks the world to step one second (in a run)
//     and polls; the next tick waits for that job, and a busy host slows the run down instead of
//     skipping seconds.
// docs/daemon.md, "Threads" and "Time scale"; docs/architecture.md, "The path of one sample".
#pragma once

#include <chrono>
#include <cstdint>
#include <expected>
#include <functional>
#include <memory>
#include <optional>
#include <string>

#include "fogbench/daemon/tick_input.hpp"
#include "fogbench/drivers/chamber.hpp"
#include "fogbench/drivers/gyro_bus.hpp"
#include "fogbench/drivers/thermistor_module.hpp"

namespace boost::asio {
class io_context;
}

namespace fogbench::daemon {

// The mock bench's paced world: steps the simulated world one second (its frames are then in the
// gyro socket and its registers show the second's end). Blocking: called on the device worker.
class PacedWorld {
 public:
  virtual ~PacedWorld() = default;
  virtual std::expected<void, std::string> step_second() = 0;
};

// Opens the gyro bus into `bus` when it is empty, reopens it otherwise (after a link loss).
using GyroOpener = std::function<drivers::Result<void>(std::optional<drivers::GyroBus>& bus)>;

// The acquisition's time, for a test to hold by hand (tests/daemon/acquisition_test.cpp, "by
// hand"): the schedule's clock and wake-ups on it. None given (the daemon): the steady clock, the
// loop's timers, and the devices' jobs on their worker threads. Given, the devices' jobs are
// posted to the loop too, so between a test's steps nothing runs beside the loop.
class LoopTime {
 public:
  using Clock = std::chrono::steady_clock;
  // One wake-up: `fire` runs on the loop once the clock has reached `at`. Setting it again or
  // cancelling drops the pending one (its `fire` never runs).
  class Alarm {
   public:
    virtual ~Alarm() = default;
    virtual void set(Clock::time_point at, std::function<void()> fire) = 0;
    virtual void cancel() = 0;
  };
  virtual ~LoopTime() = default;
  virtual Clock::time_point now() const = 0;
  virtual std::unique_ptr<Alarm> alarm() = 0;
};

struct AcquisitionDevices {
  std::unique_ptr<drivers::Chamber> chamber;
  std::unique_ptr<drivers::ThermistorSource> thermistors;
  GyroOpener open_gyro;
  std::unique_ptr<PacedWorld> paced;  // none: the real clock
};

struct AcquisitionOptions {
  double time_scale = 1.0;        // daemon seconds per wall second
  std::size_t units = 0;          // configured units: the size of TickInput::units
  double safe_setpoint_c = 20.0;  // written at start-up and on the way out, degC
  LoopTime* time = nullptr;       // a test's hand on time (outlives the acquisition); none: real
};

// Where the seconds go. on_tick answers second k's readings with the setpoint the chamber should
// hold now (degC); run_active says whether a run is on (the paced world steps only in a run).
struct TickSink {
  std::function<double(std::int64_t k, const TickInput& in)> on_tick;
  std::function<bool()> run_active;
};

// For the metrics (web_metrics.cpp).
struct AcquisitionStats {
  std::int64_t ticks = 0, ticks_skipped = 0, polls_late = 0, paced_slowed = 0;
  double tick_late_s = 0.0, tick_late_max_s = 0.0;
};

// The gyro bus's sample of one period into the units' readings, unit by unit: axis 0's rate and
// frame counts, and a three-axis unit's axes 1 and 2 (UnitReading::extra_axes).
void fill_gyro_readings(const drivers::BusSample& s, std::vector<UnitReading>& units);

class Acquisition {
 public:
  Acquisition(boost::asio::io_context& io, AcquisitionOptions options, AcquisitionDevices devices, TickSink sink);
  ~Acquisition();  // stops and joins the device threads
  Acquisition(const Acquisition&) = delete;
  Acquisition& operator=(const Acquisition&) = delete;

  // On the loop: the chamber's bring-up (safe setpoint, running), the gyro bus, the schedule.
  void start();
  // On the loop: the schedule and the gyro bus stop, then the chamber is sent to its safe
  // setpoint on the device worker; `done` runs on the loop with the error ("" when written).
  void stop(std::function<void(const std::string& error)> done);
  // Lets the device workers finish their jobs and joins them (after the loop has stopped).
  void join();

  AcquisitionStats stats() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace fogbench::daemon
