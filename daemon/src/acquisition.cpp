// The acquisition: the device threads, the gyro bus on the loop, and the one loop of seconds for
// both clocks, each a ReadingClock (acquisition.hpp). Moved out of server.cpp (issue 26).
#include "acquisition.hpp"

#include <boost/asio.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <thread>

#include <spdlog/spdlog.h>

#include "fogbench/daemon/config.hpp"
#include "repeat_log.hpp"
#include "schedule.hpp"

namespace fogbench::daemon {

namespace asio = boost::asio;
using Clock = std::chrono::steady_clock;

namespace {

// What the workers read from the chamber and the thermistor module at one poll.
struct DeviceReading {
  std::optional<double> chamber_c;
  std::optional<double> chamber_setpoint_c;
  bool alarm = false;
  bool chamber_ok = false;
  std::string chamber_error;
  bool thermistors_ok = false;
  std::string thermistor_error;
  std::vector<UnitReading> coils;  // t1_c, t2_c and out_of_range only
};

// A worker thread: an io_context used as a job queue. With a test's time (LoopTime) its jobs go
// to the loop instead (`on`), and no thread is started.
struct Worker {
  asio::io_context io;
  asio::io_context* on = nullptr;
  std::optional<asio::executor_work_guard<asio::io_context::executor_type>> guard;
  std::thread thread;

  asio::io_context::executor_type jobs() { return on ? on->get_executor() : io.get_executor(); }
  void start() {
    if (on) return;
    guard.emplace(io.get_executor());
    thread = std::thread([this] { io.run(); });
  }
  // Lets the queued jobs run (`drain`) or drops them, then joins.
  void join(bool drain) {
    if (!thread.joinable()) return;
    guard.reset();
    if (!drain) io.stop();
    thread.join();
  }
};

// The daemon's time: the steady clock and the loop's timers.
class SteadyTime final : public LoopTime {
 public:
  explicit SteadyTime(asio::io_context& io) : io_(io) {}
  Clock::time_point now() const override { return Clock::now(); }
  std::unique_ptr<Alarm> alarm() override { return std::make_unique<SteadyAlarm>(io_); }

 private:
  class SteadyAlarm final : public Alarm {
   public:
    explicit SteadyAlarm(asio::io_context& io) : timer_(io) {}
    void set(Clock::time_point at, std::function<void()> fire) override {
      timer_.expires_at(at);
      timer_.async_wait([fire = std::move(fire)](boost::system::error_code ec) {
        if (!ec) fire();
      });
    }
    void cancel() override { timer_.cancel(); }

   private:
    asio::steady_timer timer_;
  };
  asio::io_context& io_;
};

}  // namespace

void fill_gyro_readings(const drivers::BusSample& s, std::vector<UnitReading>& units) {
  for (std::size_t i = 0; i < s.units.size() && i < units.size(); ++i) {
    UnitReading& u = units[i];
    u.gyro_dph = s.units[i].rate_dph;
    u.frames = s.units[i].frames;
    u.frames_lost = s.units[i].frames_lost;
    u.frames_corrupt = s.units[i].frames_corrupt;
    u.gyro_starts = s.units[i].starts;
    u.frames_saturated = s.units[i].frames_saturated;
    u.extra_axes.clear();
    if (i < s.extra_axes.size())
      for (const drivers::GyroSample& a : s.extra_axes[i])
        u.extra_axes.push_back(
            {.rate_dph = a.rate_dph,
             .frames = a.frames,
             .frames_lost = a.frames_lost,
             .frames_corrupt = a.frames_corrupt,
             .frames_saturated = a.frames_saturated});
  }
}

struct Acquisition::Impl {
  asio::io_context& io;
  AcquisitionOptions options;
  std::unique_ptr<LoopTime> steady_time;  // the daemon's, when no test holds time
  LoopTime& time;
  TickSink sink;
  AcquisitionStats stats;

  // The device worker: the chamber, and with the paced clock the world and the module too.
  Worker dev;
  std::unique_ptr<drivers::Chamber> chamber;
  std::unique_ptr<drivers::ThermistorSource> thermistors;
  // The thermistor module's own worker (polls only; with the paced clock the module is read on
  // the device worker, in the job of each second, and this one stays idle).
  Worker therm;

  // The gyro bus: read on the loop through its fd.
  GyroOpener open_bus;
  std::optional<drivers::GyroBus> bus;
  asio::posix::stream_descriptor gyro_sd{io};
  asio::steady_timer gyro_retry{io};
  std::vector<::can_frame> frames;
  bool gyro_logged_down = false;

  // The one loop: second k is closed at t0 + k periods by one timer, once the clock has its
  // readings (the real clock's never wait; the paced clock's tick waits for its job).
  std::unique_ptr<LoopTime::Alarm> timer;
  Schedule sched{};       // t0 and the half period; its timing decisions (schedule.hpp)
  std::int64_t k = 0;     // the second the next tick closes
  bool waiting = false;   // tick k was due before its readings were in
  bool stopped = false;

  // How a second's readings are made: asked for after the previous tick, waited for (or not),
  // and what a late loop does. acquisition.hpp, "One schedule, two clocks".
  struct ReadingClock {
    virtual ~ReadingClock() = default;
    // After tick `second` - 1 (0: at the start): asks for that second's readings, then arms the loop's
    // timer (Impl::arm_tick), having skipped the seconds it was too late for (Impl::skip_to).
    virtual void ask(std::int64_t second) = 0;
    // Tick `second` is due, woken at `now`: the second to close now (later: the ones before it skipped).
    virtual std::int64_t resume(std::int64_t second, Clock::time_point now) = 0;
    // Whether second k's readings are in; until they are, the tick waits (Impl::readings_in).
    virtual bool ready() const = 0;
    // Before the second's gyro sample is closed.
    virtual void close_gyro() {}
    // Second k's chamber and coils into `in` (its gyro part already in): false when the second
    // is not handed to the sink.
    virtual bool fill(TickInput& in) = 0;
    // The sink's answer for second k: the setpoint the chamber should hold, degC.
    virtual void commanded(double setpoint_c) = 0;
    virtual void stop() {}
  };
  struct RealClock;
  struct PacedClock;
  std::unique_ptr<ReadingClock> clock;

  // The latest reading: its chamber part and its thermistor part arrive separately on the real
  // clock (a stalled module does not hold up the chamber's value), each with its own freshness.
  std::optional<DeviceReading> reading;
  bool have_chamber = false, have_coils = false;  // each part arrived at least once
  bool new_chamber = false, new_coils = false;    // arrived since the last tick

  std::optional<double> written_setpoint_c;
  bool write_in_flight = false;
  RepeatLog setpoint_log;  // "setpoint not written", at most once a minute
  // The gyro transport's news about its stream (GyroBus::take_events), a line a minute per kind,
  // logged and handed to the next second (TickInput::gyro_stream_events).
  RepeatLogSet gyro_stream_log;
  std::vector<std::string> gyro_stream_pending;

  Impl(asio::io_context& i, AcquisitionOptions o, AcquisitionDevices d, TickSink s);  // after the clocks

  void note_lateness(Clock::time_point due) {
    ++stats.ticks;
    stats.tick_late_s = std::max(0.0, std::chrono::duration<double>(time.now() - due).count());
    stats.tick_late_max_s = std::max(stats.tick_late_max_s, stats.tick_late_s);
  }

  // --- start-up and the way out
  void start() {
    dev.start();
    therm.start();
    // The chamber goes to its safe setpoint and runs, before anything else is asked.
    const double safe = options.safe_setpoint_c;
    asio::post(dev.jobs(), [this, safe] {
      auto report = chamber->bring_up();
      std::string msg = report ? report->to_string() : report.error().to_string();
      auto w = chamber->write_setpoint_c(safe);
      auto r = chamber->set_running(true);
      std::string err = !w ? w.error().to_string() : (!r ? r.error().to_string() : "");
      asio::post(io, [this, msg, err, safe] {
        spdlog::info("chamber bring-up:\n{}", msg);
        if (err.empty()) {
          written_setpoint_c = safe;
          spdlog::info("chamber at the safe setpoint {} C", safe);
        } else {
          spdlog::warn("chamber not yet at the safe setpoint: {} (retried every second)", err);
        }
      });
    });
    open_gyro();
    sched.t0 = time.now() + sched.period();
    k = 0;
    clock->ask(k);
  }

  void stop(std::function<void(const std::string&)> done) {
    stopped = true;
    timer->cancel();
    clock->stop();
    gyro_retry.cancel();
    if (gyro_sd.is_open()) (void)gyro_sd.release();  // the bus owns and closes the fd
    const double safe = options.safe_setpoint_c;
    asio::post(dev.jobs(), [this, safe, done = std::move(done)] {
      auto r = chamber->write_setpoint_c(safe);
      std::string err = r ? "" : r.error().to_string();
      asio::post(io, [done, err] { done(err); });
    });
  }

  // --- the chamber's setpoint
  void post_write_setpoint(double sp_c) {
    if (write_in_flight) return;  // the next tick retries with the then-current setpoint
    write_in_flight = true;
    asio::post(dev.jobs(), [this, sp_c] {
      auto r = chamber->write_setpoint_c(sp_c);
      std::string err = r ? "" : r.error().to_string();
      asio::post(io, [this, sp_c, err] {
        write_in_flight = false;
        setpoint_written(sp_c, err);
      });
    });
  }
  // A write's outcome (err empty: written). A chamber that is off refuses every second's write:
  // the warning is logged once a minute with its count, not every second (repeat_log.hpp).
  void setpoint_written(double sp_c, const std::string& err) {
    if (err.empty()) {
      written_setpoint_c = sp_c;
      if (setpoint_log.active()) {
        for (const auto& line : setpoint_log.cleared()) spdlog::warn("{}", line);
        spdlog::info("setpoint {} C written again", sp_c);
      }
      return;
    }
    for (const auto& line : setpoint_log.occurred(repeat_key(err), fmt::format("setpoint {} C not written: {}", sp_c, err), time.now()))
      spdlog::warn("{}", line);
  }
  bool setpoint_unwritten(double sp_c) const { return !written_setpoint_c || *written_setpoint_c != sp_c; }

  // --- the devices' readings
  // On a worker: one poll of the chamber and the thermistor module.
  DeviceReading read_devices() {
    DeviceReading d;
    read_chamber(d);
    read_thermistors(d);
    return d;
  }
  void read_chamber(DeviceReading& d) {
    if (auto r = chamber->poll()) {
      d.chamber_ok = true;
      d.chamber_c = r->process_value_c;
      d.chamber_setpoint_c = r->setpoint_c;
      d.alarm = r->alarm;
    } else {
      d.chamber_error = r.error().to_string();
    }
  }
  void read_thermistors(DeviceReading& d) {
    d.coils.resize(options.units);
    if (auto t = thermistors->read_all()) {
      d.thermistors_ok = true;
      for (std::size_t i = 0; i < t->size() && i < d.coils.size(); ++i) {
        const auto& c = (*t)[i];
        auto take = [&](const drivers::Result<double>& v, std::optional<double>& out) {
          if (v) out = *v;
          else if (v.error().code == drivers::ErrorCode::out_of_range) d.coils[i].out_of_range = true;
        };
        take(c.t1_c, d.coils[i].t1_c);
        take(c.t2_c, d.coils[i].t2_c);
        // y's and z's own coil, where configured per axis.
        d.coils[i].axis_t1_c.assign(c.axis_t1_c.size(), std::nullopt);
        d.coils[i].axis_t2_c.assign(c.axis_t2_c.size(), std::nullopt);
        for (std::size_t a = 0; a < c.axis_t1_c.size() && a < c.axis_t2_c.size(); ++a) {
          take(c.axis_t1_c[a], d.coils[i].axis_t1_c[a]);
          take(c.axis_t2_c[a], d.coils[i].axis_t2_c[a]);
        }
      }
    } else {
      d.thermistor_error = t.error().to_string();
    }
  }

  // On the loop: a poll's results become the current reading, each device's part on its own.
  void take_chamber(const DeviceReading& d) {
    if (have_chamber && reading->chamber_ok != d.chamber_ok) {
      if (d.chamber_ok) spdlog::info("chamber link up");
      else spdlog::warn("chamber: {}", d.chamber_error);
    }
    // A controller that was away may have restarted with another setpoint: once the link
    // is back the setpoint is written again, not assumed.
    if (!d.chamber_ok) written_setpoint_c.reset();
    if (!reading) reading.emplace();
    reading->chamber_ok = d.chamber_ok;
    reading->chamber_error = d.chamber_error;
    reading->chamber_c = d.chamber_c;
    reading->chamber_setpoint_c = d.chamber_setpoint_c;
    reading->alarm = d.alarm;
    have_chamber = new_chamber = true;
  }
  void take_thermistors(const DeviceReading& d) {
    if (have_coils && reading->thermistors_ok != d.thermistors_ok) {
      if (d.thermistors_ok) spdlog::info("thermistor module link up");
      else spdlog::warn("thermistor module: {}", d.thermistor_error);
    }
    if (!reading) reading.emplace();
    reading->thermistors_ok = d.thermistors_ok;
    reading->thermistor_error = d.thermistor_error;
    reading->coils = d.coils;
    have_coils = new_coils = true;
  }

  // --- the gyro bus
  void open_gyro() {
    if (stopped) return;
    drivers::Result<void> ok = open_bus(bus);
    if (!ok || !bus) {
      if (!gyro_logged_down)
        spdlog::warn("gyro bus: {}; retrying every second of run time",
                     ok ? std::string("not opened") : ok.error().to_string());
      gyro_logged_down = true;
      retry_gyro();
      return;
    }
    gyro_logged_down = false;
    spdlog::info("gyro bus: {}", bus->transport().describe());
    boost::system::error_code ec;
    gyro_sd.assign(bus->fd(), ec);
    if (ec) spdlog::error("gyro bus fd: {}", ec.message());
    wait_gyro();
  }

  void retry_gyro() {
    gyro_retry.expires_after(gyro_retry_delay(options.time_scale));
    gyro_retry.async_wait([this](boost::system::error_code ec) {
      if (!ec) open_gyro();
    });
  }

  void wait_gyro() {
    gyro_sd.async_wait(asio::posix::stream_descriptor::wait_read, [this](boost::system::error_code ec) {
      if (ec || stopped) return;
      // Bounded per turn so a flood of frames cannot starve the sockets and the schedule.
      for (int i = 0; i < 16; ++i) {
        auto n = bus->read_frames(frames);
        if (!n) {
          spdlog::warn("gyro bus: {}", n.error().to_string());
          (void)gyro_sd.release();  // the bus owns and closes the fd
          retry_gyro();
          return;
        }
        if (*n == 0) break;
      }
      take_gyro_events();
      wait_gyro();
    });
  }

  void take_gyro_events() {
    // Bounded: a second holds at most this many lines (each already a kind's first or its
    // minute's line, so more only comes from many kinds at once).
    constexpr std::size_t kMaxLinesPerSecond = 64;
    for (const auto& e : bus->take_events())
      for (auto& line : gyro_stream_log.occurred(e.message, time.now())) {
        spdlog::warn("gyro stream: {}", line);
        if (gyro_stream_pending.size() < kMaxLinesPerSecond) gyro_stream_pending.push_back(std::move(line));
      }
  }


  // --- the one loop
  // After the clock asked for second k's readings: tick k is due at t0 + k periods (an absolute
  // deadline from t0: a late wake-up never shifts the next one).
  void arm_tick() {
    timer->set(sched.tick_due(k), [this] {
      if (!stopped) on_due();
    });
  }

  void on_due() {
    if (const std::int64_t to = clock->resume(k, time.now()); to != k) skip_to(to);
    if (clock->ready()) tick();
    else waiting = true;  // the readings' arrival ticks (readings_in)
  }

  // The clock: second k's readings are in.
  void readings_in() {
    if (waiting && !stopped) {
      waiting = false;
      tick();
    }
  }

  // The clock was too late for seconds k..to-1: they are still seconds of the run, stored as not
  // read (flagged missing), so a run has every second of its clock and the count of its samples
  // says how long it ran. Measured by scripts/soak: holes appeared here at 500x.
  void skip_to(std::int64_t to) {
    for (; k < to; ++k) tick_unread(k);
  }

  // Second k is closed: its TickInput to the sink, the setpoint back to the clock, then the clock
  // is asked for the next second.
  void tick() {
    note_lateness(sched.tick_due(k));
    const std::int64_t s = k++;
    clock->close_gyro();
    TickInput in = new_input();
    fill_gyro(in);
    if (clock->fill(in)) clock->commanded(sink.on_tick(s, in));
    clock->ask(k);
  }

  TickInput new_input() const {
    TickInput in;
    in.wall_time = std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
    in.units.resize(options.units);
    return in;
  }
  // The gyro's averages since the last tick.
  void fill_gyro(TickInput& in) {
    in.gyro_read = in.gyro_link_up = bus && gyro_sd.is_open();
    if (!bus) {
      in.gyro_stream_events = std::exchange(gyro_stream_pending, {});
      return;
    }
    auto s = bus->close_samples();
    // A silence is judged at the sample's close (a serial line's dead_line), when the bus has
    // nothing to read: take its news here too, not only after a read.
    take_gyro_events();
    in.gyro_stream_events = std::exchange(gyro_stream_pending, {});
    fill_gyro_readings(s, in.units);
  }
  static void fill_chamber(TickInput& in, const DeviceReading& d) {
    in.chamber_c = d.chamber_c;
    in.chamber_setpoint_c = d.chamber_setpoint_c;
    in.chamber_alarm = d.alarm;
    in.chamber_link_down = !d.chamber_ok;
  }
  static void fill_coils(TickInput& in, const DeviceReading& d) {
    for (std::size_t i = 0; i < in.units.size() && i < d.coils.size(); ++i) {
      in.units[i].t1_c = d.coils[i].t1_c;
      in.units[i].t2_c = d.coils[i].t2_c;
      in.units[i].axis_t1_c = d.coils[i].axis_t1_c;
      in.units[i].axis_t2_c = d.coils[i].axis_t2_c;
      in.units[i].out_of_range = d.coils[i].out_of_range;
    }
  }

  // A second the loop was too late to acquire: nothing read, the profile steps on.
  void tick_unread(std::int64_t s) {
    ++stats.ticks_skipped;
    TickInput in = new_input();
    in.late = true;
    in.gyro_read = false;  // its frames go into the next period's sample
    in.gyro_link_up = bus && gyro_sd.is_open();
    clock->commanded(sink.on_tick(s, in));
  }
};

// The real clock: second k's devices are polled at t0 + (k - 1/2) periods (its own timer, armed
// between tick k - 1 and that poll only, so the loop's events keep the order of the half-period
// slots: poll, tick, poll, ...), the temperatures read mid-way through the gyro's averaging
// window and fresh at the tick. A tick never waits: a part that did not arrive stands in once
// from the period before, then is missing. A loop far behind skips ahead (Schedule).
struct Acquisition::Impl::RealClock final : Acquisition::Impl::ReadingClock {
  Impl& a;
  std::unique_ptr<LoopTime::Alarm> poll_timer;
  bool chamber_in_flight = false, coils_in_flight = false;  // a poll of the device is under way
  int stale_chamber = 0, stale_coils = 0;                   // ticks since a new part was used

  explicit RealClock(Impl& impl) : a(impl), poll_timer(impl.time.alarm()) {}

  void ask(std::int64_t second) override {
    poll_timer->set(a.sched.slot_due(2 * second - 1), [this] {  // the first, k = 0: slot -1
      if (a.stopped) return;
      const std::int64_t slot = resume_slot(2 * a.k - 1, a.time.now());
      a.skip_to((slot + 1) / 2);
      post_poll();
      a.arm_tick();
    });
  }
  std::int64_t resume(std::int64_t second, Clock::time_point now) override { return resume_slot(2 * second, now) / 2; }
  // Far behind (the loop was blocked, e.g. by a long fit): skip ahead rather than replay a burst
  // of empty seconds; from a poll's slot to a poll's, from a tick's to a tick's.
  std::int64_t resume_slot(std::int64_t slot, Clock::time_point now) const {
    const std::int64_t to = a.sched.real_resume_slot(slot, now);
    if (to != slot)
      spdlog::warn("acquisition {} half-periods late; skipping ahead", (now - a.sched.slot_due(slot)) / a.sched.half_period);
    return to;
  }
  bool ready() const override { return true; }
  void stop() override { poll_timer->cancel(); }

  // The chamber on the device worker, the module on its own thread: a stalled module (or
  // chamber) must not make the other's readings late. A device whose last poll is still blocked
  // in its call is not asked again.
  void post_poll() {
    post_read(chamber_in_flight, a.dev, &Impl::read_chamber, &Impl::take_chamber);
    post_read(coils_in_flight, a.therm, &Impl::read_thermistors, &Impl::take_thermistors);
  }
  // One device's read on `worker` unless the last one is in flight; its result taken on the loop.
  void post_read(bool& in_flight, Worker& worker, void (Impl::*read)(DeviceReading&),
                 void (Impl::*take)(const DeviceReading&)) {
    if (in_flight) return;
    in_flight = true;
    asio::post(worker.jobs(), [this, &in_flight, read, take] {
      DeviceReading d;
      (a.*read)(d);
      asio::post(a.io, [this, &in_flight, take, d = std::move(d)] {
        in_flight = false;
        (a.*take)(d);
      });
    });
  }

  bool fill(TickInput& in) override {
    // The poll of this period normally arrived half a period ago. When a part of it is late (a
    // loaded machine at a high time scale, a stalled device), the previous one, one period old,
    // stands in once: a settle judged on "every reading in band" would otherwise restart at
    // each late poll. Older than that, its values are missing, and the sink is told the loop
    // was late for them (a run that fails says so).
    auto usable = [&](bool have, bool& fresh, int& stale) {
      if (!have) return false;
      if (fresh) {
        fresh = false;
        stale = 0;
        return true;
      }
      if (stale++ < 1) {
        ++a.stats.polls_late;
        return true;
      }
      return false;
    };
    if (usable(a.have_chamber, a.new_chamber, stale_chamber)) {
      fill_chamber(in, *a.reading);
    } else if (a.have_chamber) {
      in.chamber_link_down = !a.reading->chamber_ok;
      in.late = true;
    }
    if (usable(a.have_coils, a.new_coils, stale_coils)) fill_coils(in, *a.reading);
    else if (a.have_coils) in.late = true;
    return true;
  }
  // Written when it is not the chamber's yet.
  void commanded(double setpoint_c) override {
    if (a.setpoint_unwritten(setpoint_c)) a.post_write_setpoint(setpoint_c);
  }
};

// The paced clock (the mock bench's): second k is acquired once a job on the device worker has
// written the setpoint of tick k - 1, asked the world to step one second (in a run: its frames
// are then in the gyro socket) and polled the devices; tick k waits for that job rather than its
// wall time alone. A busy host moves t0 forward (Schedule) instead of skipping seconds.
struct Acquisition::Impl::PacedClock final : Acquisition::Impl::ReadingClock {
  // The job of one paced second, once done.
  struct Result {
    DeviceReading reading;
    bool asked = false;     // the job asked the world to step (a run was active)
    bool advanced = false;  // and it did: the world stepped one second for this tick
  };

  Impl& a;
  std::unique_ptr<PacedWorld> world;
  std::optional<Result> result;  // the job of second a.k, once done
  double commanded_setpoint_c;   // the sink's last answer, degC
  Clock::time_point slowed_logged{};
  bool logged_down = false;

  PacedClock(Impl& impl, std::unique_ptr<PacedWorld> w)
      : a(impl), world(std::move(w)), commanded_setpoint_c(impl.options.safe_setpoint_c) {}

  void ask(std::int64_t second) override {
    if (second == 0) {  // the start: no setpoint of a tick yet, and no run
      post_job(false, std::nullopt);
    } else {
      std::optional<double> sp;
      if (a.setpoint_unwritten(commanded_setpoint_c)) sp = commanded_setpoint_c;
      post_job(a.sink.run_active(), sp);
      // Behind the schedule by more than two periods (the host is busy): the schedule moves back
      // rather than catching up in a burst. The run goes on slower than the time scale, and
      // every second is acquired as it would be on an idle host.
      const auto now = a.time.now();
      if (const auto shift = a.sched.paced_shift(second, now); shift.count() > 0) {
        a.sched.t0 += shift;
        ++a.stats.paced_slowed;
        if (now - slowed_logged > std::chrono::seconds(10)) {
          slowed_logged = now;
          spdlog::info("simulated clock: slower than time scale {} (a busy host); {} tick(s) waited so far",
                       a.options.time_scale, a.stats.paced_slowed);
        }
      }
    }
    a.arm_tick();
  }
  std::int64_t resume(std::int64_t second, Clock::time_point) override { return second; }  // never skips
  bool ready() const override { return result.has_value(); }

  // The job: the setpoint of the last tick, one simulated second (in a run), then the poll. In
  // this order on the worker, so the world steps under the setpoint the sink commanded and the
  // poll reads the end of that second.
  void post_job(bool advance, std::optional<double> setpoint_c) {
    asio::post(a.dev.jobs(), [this, advance, setpoint_c] {
      Result r;
      r.asked = advance;
      std::string write_error, clock_error;
      if (setpoint_c)
        if (auto w = a.chamber->write_setpoint_c(*setpoint_c); !w) write_error = w.error().to_string();
      if (advance) {
        if (auto t = world->step_second()) r.advanced = true;
        else clock_error = t.error();
      }
      r.reading = a.read_devices();
      if (!clock_error.empty()) {
        // The world did not move: nothing of this second was read. As a bench that does not
        // answer, the chamber counts as unreachable (link_loss decides).
        r.reading = DeviceReading{};
        r.reading.coils.resize(a.options.units);
        r.reading.chamber_error = r.reading.thermistor_error = "simulated clock: " + clock_error;
      }
      asio::post(a.io, [this, setpoint_c, write_error, clock_error, r = std::move(r)]() mutable {
        if (setpoint_c) a.setpoint_written(*setpoint_c, write_error);
        if (!clock_error.empty()) {
          if (!logged_down) spdlog::error("simulated clock: {}", clock_error);
          logged_down = true;
        } else if (r.advanced && logged_down) {
          spdlog::info("simulated clock: stepping again");
          logged_down = false;
        }
        result = std::move(r);
        a.readings_in();
      });
    });
  }

  // Every frame of the second the world stepped is in the socket: read them all now.
  void close_gyro() override {
    if (a.bus && a.gyro_sd.is_open())
      for (int i = 0; i < 1000; ++i) {
        auto n = a.bus->read_frames(a.frames);
        if (!n || *n == 0) break;
      }
  }

  bool fill(TickInput& in) override {
    Result r = std::move(*result);
    result.reset();
    in.gyro_read = in.gyro_read && r.advanced;  // a world that did not step sent nothing
    // A run was asked for after this second's job was sent, so the world did not move for it:
    // its first second is the next, one the world steps through. A run's samples then depend on
    // the seed and the runs before it, not on when it was started.
    if (!r.asked && a.sink.run_active()) return false;
    a.take_chamber(r.reading);
    a.take_thermistors(r.reading);
    a.new_chamber = a.new_coils = false;
    fill_chamber(in, r.reading);
    fill_coils(in, r.reading);
    return true;
  }
  // Written in the next second's job.
  void commanded(double setpoint_c) override { commanded_setpoint_c = setpoint_c; }
};

Acquisition::Impl::Impl(asio::io_context& i, AcquisitionOptions o, AcquisitionDevices d, TickSink s)
    : io(i), options(o), steady_time(o.time ? nullptr : std::make_unique<SteadyTime>(i)),
      time(o.time ? *o.time : *steady_time), sink(std::move(s)), chamber(std::move(d.chamber)),
      thermistors(std::move(d.thermistors)), open_bus(std::move(d.open_gyro)), timer(time.alarm()) {
  if (o.time) dev.on = therm.on = &io;
  sched.half_period = std::chrono::nanoseconds(static_cast<std::int64_t>(std::llround(0.5e9 / options.time_scale)));
  if (d.paced) clock = std::make_unique<PacedClock>(*this, std::move(d.paced));
  else clock = std::make_unique<RealClock>(*this);
}

Acquisition::Acquisition(asio::io_context& io, AcquisitionOptions options, AcquisitionDevices devices, TickSink sink)
    : impl_(std::make_unique<Impl>(io, options, std::move(devices), std::move(sink))) {}

Acquisition::~Acquisition() {
  impl_->dev.join(false);
  impl_->therm.join(false);
  if (impl_->gyro_sd.is_open()) (void)impl_->gyro_sd.release();  // the bus closes its fd
}

void Acquisition::start() { impl_->start(); }

void Acquisition::stop(std::function<void(const std::string&)> done) { impl_->stop(std::move(done)); }

void Acquisition::join() {
  impl_->dev.join(true);
  impl_->therm.join(false);
}

AcquisitionStats Acquisition::stats() const { return impl_->stats; }

}  // namespace fogbench::daemon
