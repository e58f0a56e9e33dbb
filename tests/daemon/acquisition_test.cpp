// The acquisition (daemon/src/acquisition.hpp) with fake devices in-process: a chamber, a
// thermistor module and a gyro bus transport whose values are numbered by their poll, on the
// real clock (at a time scale of 4) and on the paced clock (a fake world). No process, no
// socket to a mock bench; nothing here asserts a duration: the watchdog only ends a stuck loop.
// A late loop (its catch-up, its skipped seconds, the paced clock slowed) is driven by hand: a
// LoopTime the test moves, the devices' jobs on the loop, every second asserted exactly, no sleep.
#include <sys/eventfd.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <mutex>
#include <map>
#include <set>
#include <utility>
#include <vector>

#include <boost/asio.hpp>
#include <catch2/catch.hpp>

#include "../../daemon/src/acquisition.hpp"
#include "fogbench/drivers/can_frame.hpp"

using namespace fogbench;
using namespace fogbench::daemon;
namespace asio = boost::asio;

namespace {

constexpr std::size_t kUnits = 2;
constexpr int kFramesPerSecond = 10;

// A gyro bus transport fed by the test: frames pushed are readable through an eventfd.
class FakeTransport final : public drivers::CanTransport {
 public:
  // `news_at_close`: the sample close (GyroBus::close_samples, numbered from 1) at which the
  // transport reports a silence of its own, with nothing to read (a serial line's dead_line).
  explicit FakeTransport(int news_at_close = 0)
      : fd_(::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC)), news_at_close_(news_at_close) {}
  ~FakeTransport() override { ::close(fd_); }
  // Frames, and what the transport found wrong in the stream beside them (a serial line's news).
  void push(const std::vector<::can_frame>& frames, std::vector<std::string> news = {}) {
    std::lock_guard lock(m_);
    queue_.insert(queue_.end(), frames.begin(), frames.end());
    for (auto& message : news) events_.push_back({std::chrono::system_clock::now(), std::move(message)});
    const std::uint64_t one = 1;
    (void)!::write(fd_, &one, sizeof one);
  }
  std::vector<Event> take_events() override {
    std::lock_guard lock(m_);
    return std::exchange(events_, {});
  }
  void sample_closed() noexcept override {
    std::lock_guard lock(m_);
    if (++closes_ == news_at_close_) {
      events_.push_back({std::chrono::system_clock::now(), "fake0: dead_line: no byte received in 3 sample periods"});
    }
  }
  int fd() const noexcept override { return fd_; }
  drivers::Result<std::size_t> read(std::vector<::can_frame>& out) override {
    std::lock_guard lock(m_);
    std::uint64_t n = 0;
    (void)!::read(fd_, &n, sizeof n);
    const std::size_t got = queue_.size();
    out.insert(out.end(), queue_.begin(), queue_.end());
    queue_.clear();
    return got;
  }
  std::uint64_t malformed() const noexcept override { return 0; }
  std::string describe() const override { return "fake transport"; }

 private:
  int fd_;
  int news_at_close_;
  int closes_ = 0;
  std::mutex m_;
  std::vector<::can_frame> queue_;
  std::vector<Event> events_;
};

// The fake bench: every device numbers its polls from 1 and answers with values of that number.
// Chamber poll n: air 20 + 0.5 n degC; with it (even when the chamber fails) the gyros send the
// frames of second n, unit u at n + 0.1 u deg/h. Thermistor read n: T1 30 + n, T2 40 + n degC
// (+ 0.5 for unit 1). Touched on the device workers, read by the test once they are joined.
struct Bench {
  std::mutex m;
  int chamber_polls = 0, coil_reads = 0, steps = 0;
  std::set<int> chamber_down;      // chamber polls that fail as a lost link (its writes fail meanwhile)
  std::set<int> module_down;       // thermistor reads that fail as a lost link
  std::set<int> unit1_t2_open;     // thermistor reads where unit 1's T2 reads open
  std::set<int> unit1_gyro_silent; // chamber polls after which unit 1 sends no frame
  std::set<int> step_fails;        // paced world steps (numbered from 1) that fail
  std::map<int, std::vector<std::string>> stream_news;  // chamber polls after which the transport reports these
  int news_at_close = 0;           // the sample close at which the transport reports a silence
  bool link_down = false;
  double setpoint_c = 0.0;
  std::vector<double> written;     // setpoints written, in order
  FakeTransport* transport = nullptr;
  std::uint8_t sequence[kUnits] = {0, 0};

  std::vector<::can_frame> frames_of(int n, bool unit1) {
    std::vector<::can_frame> f;
    for (int i = 0; i < kFramesPerSecond; ++i)
      for (std::size_t u = 0; u < kUnits; ++u) {
        if (u == 1 && !unit1) continue;
        drivers::can::GyroFrame g;
        g.node_id = static_cast<std::uint16_t>(u + 1);
        g.counts = n * 1000 + static_cast<int>(u) * 100;  // 0.001 deg/h per count
        g.sequence = sequence[u]++;
        g.status = drivers::can::status::valid;
        f.push_back(drivers::can::encode(g));
      }
    return f;
  }
};

class FakeChamber final : public drivers::Chamber {
 public:
  explicit FakeChamber(Bench& b) : b_(b) {}
  drivers::Result<drivers::BringUpReport> bring_up() override { return drivers::BringUpReport{}; }
  drivers::Result<void> write_setpoint_c(double c) override {
    std::lock_guard lock(b_.m);
    if (b_.link_down) return drivers::fail(drivers::ErrorCode::connection, "fake chamber: link down");
    b_.setpoint_c = c;
    b_.written.push_back(c);
    return {};
  }
  drivers::Result<void> set_running(bool) override { return {}; }
  drivers::Result<drivers::ChamberReading> poll() override {
    std::lock_guard lock(b_.m);
    const int n = ++b_.chamber_polls;
    b_.transport->push(b_.frames_of(n, !b_.unit1_gyro_silent.contains(n)),  // the gyros' own bus
                       b_.stream_news.contains(n) ? b_.stream_news[n] : std::vector<std::string>{});
    b_.link_down = b_.chamber_down.contains(n);
    if (b_.link_down) return drivers::fail(drivers::ErrorCode::timeout, "fake chamber: no answer");
    drivers::ChamberReading r;
    r.process_value_c = 20.0 + 0.5 * n;
    r.setpoint_c = b_.setpoint_c;
    r.running = true;
    return r;
  }

 private:
  Bench& b_;
};

class FakeModule final : public drivers::ThermistorSource {
 public:
  explicit FakeModule(Bench& b) : b_(b) {}
  drivers::Result<std::vector<drivers::CoilTemperatures>> read_all() override {
    std::lock_guard lock(b_.m);
    const int n = ++b_.coil_reads;
    if (b_.module_down.contains(n)) return drivers::fail(drivers::ErrorCode::timeout, "fake module: no answer");
    std::vector<drivers::CoilTemperatures> t(kUnits);
    for (std::size_t u = 0; u < kUnits; ++u) {
      t[u].t1_c = 30.0 + n + 0.5 * static_cast<double>(u);
      t[u].t2_c = 40.0 + n + 0.5 * static_cast<double>(u);
    }
    if (b_.unit1_t2_open.contains(n)) t[1].t2_c = drivers::fail(drivers::ErrorCode::open_circuit, "T2 open");
    return t;
  }

 private:
  Bench& b_;
};

class FakeWorld final : public PacedWorld {
 public:
  explicit FakeWorld(Bench& b) : b_(b) {}
  std::expected<void, std::string> step_second() override {
    std::lock_guard lock(b_.m);
    if (b_.step_fails.contains(++b_.steps)) return std::unexpected("fake world: no reply");
    return {};
  }

 private:
  Bench& b_;
};

struct Tick {
  std::int64_t k;
  TickInput in;
};

// A second the real clock skipped (Acquisition's tick_unread): late, its gyro not read.
bool unread(const TickInput& in) { return in.late && !in.gyro_read && in.gyro_link_up; }

// The fake bench's devices, and its gyro bus opened on a fake transport.
AcquisitionDevices fake_devices(Bench& bench, bool paced) {
  auto transport = std::make_shared<std::unique_ptr<FakeTransport>>(std::make_unique<FakeTransport>(bench.news_at_close));
  bench.transport = transport->get();
  AcquisitionDevices d;
  d.chamber = std::make_unique<FakeChamber>(bench);
  d.thermistors = std::make_unique<FakeModule>(bench);
  if (paced) d.paced = std::make_unique<FakeWorld>(bench);
  d.open_gyro = [transport](std::optional<drivers::GyroBus>& bus) -> drivers::Result<void> {
    if (bus) return {};
    std::vector<drivers::GyroChannelConfig> ch(kUnits);
    for (std::size_t u = 0; u < kUnits; ++u) {
      ch[u].node_id = static_cast<std::uint16_t>(u + 1);
      ch[u].scale_dph_per_count = 0.001;
    }
    bus.emplace(std::move(*transport), std::move(ch));
    return {};
  };
  return d;
}

// Runs an acquisition on the fake bench until `count` seconds have been read (the seconds skipped
// by a late real clock do not count); the sink answers every second with a setpoint of 25 degC,
// and a run is on from the second tick.
std::vector<Tick> acquire(Bench& bench, bool paced, std::size_t count) {
  asio::io_context io;
  AcquisitionDevices d = fake_devices(bench, paced);
  AcquisitionOptions o;
  // The real clock's tick does not wait for a poll (a late one is stood in for, then missing):
  // 4x leaves the device workers 125 ms to answer. The paced clock's tick waits for its job.
  o.time_scale = paced ? 50.0 : 4.0;
  o.units = kUnits;
  o.safe_setpoint_c = 20.0;
  std::vector<Tick> ticks;
  std::size_t read = 0;
  std::unique_ptr<Acquisition> acq;
  TickSink sink;
  sink.on_tick = [&](std::int64_t k, const TickInput& in) {
    if (read < count) {
      ticks.push_back({k, in});
      if (!unread(in) && ++read == count) asio::post(io, [&] { acq->stop([&](const std::string&) { io.stop(); }); });
    }
    return 25.0;
  };
  sink.run_active = [&] { return !ticks.empty(); };
  acq = std::make_unique<Acquisition>(io, o, std::move(d), std::move(sink));
  // A watchdog, not a measurement: a loop that stopped ticking ends here and the counts fail.
  asio::steady_timer watchdog(io, std::chrono::seconds(60));
  watchdog.async_wait([&](boost::system::error_code ec) {
    if (!ec) io.stop();
  });
  acq->start();
  io.run();
  acq->join();
  acq.reset();
  return ticks;
}

void check_consecutive(const std::vector<Tick>& ticks) {
  for (std::size_t i = 0; i < ticks.size(); ++i) CHECK(ticks[i].k == static_cast<std::int64_t>(i));
}

// Tick k read chamber poll n and thermistor read n (n = k + 1 when no second was skipped), all
// present.
void check_values(const Tick& t, std::int64_t n_poll = -1) {
  const double n = static_cast<double>(n_poll >= 0 ? n_poll : t.k + 1);
  INFO("tick " << t.k);
  REQUIRE(t.in.units.size() == kUnits);
  REQUIRE(t.in.chamber_c);
  CHECK(*t.in.chamber_c == Approx(20.0 + 0.5 * n));
  CHECK_FALSE(t.in.chamber_link_down);
  CHECK_FALSE(t.in.late);
  for (std::size_t u = 0; u < kUnits; ++u) {
    const auto& r = t.in.units[u];
    REQUIRE(r.gyro_dph);
    CHECK(*r.gyro_dph == Approx(n + 0.1 * static_cast<double>(u)));
    CHECK(r.frames == static_cast<std::uint32_t>(kFramesPerSecond));
    REQUIRE(r.t1_c);
    REQUIRE(r.t2_c);
    CHECK(*r.t1_c == Approx(30.0 + n + 0.5 * static_cast<double>(u)));
    CHECK(*r.t2_c == Approx(40.0 + n + 0.5 * static_cast<double>(u)));
  }
}

bool same(const std::optional<double>& a, const std::optional<double>& b) {
  return a.has_value() == b.has_value() && (!a || *a == Approx(*b));
}

// Time by hand (acquisition.hpp, LoopTime): the test moves the clock; the wake-ups it reaches fire
// in the order of their times (each at its own time when the loop is free by then, else at once:
// late), and the loop runs what is ready after each (the devices' jobs are posted to the loop).
class HandTime final : public LoopTime {
 public:
  explicit HandTime(asio::io_context& io) : io_(io), work_(io.get_executor()) {}
  Clock::time_point now() const override { return now_; }
  std::unique_ptr<Alarm> alarm() override { return std::make_unique<HandAlarm>(*this); }

  // A handler that takes this long (a long fit on a busy daemon): the clock moves on, and what
  // came due meanwhile fires only once the handler is done.
  void pass(Clock::duration d) { now_ += d; }
  // The loop until `to`.
  void run_until(Clock::time_point to) {
    for (;;) {
      settle();
      HandAlarm* next = nullptr;
      for (HandAlarm* a : alarms_)
        if (a->fire && a->at <= to && (!next || a->at < next->at)) next = a;
      if (!next) break;
      now_ = std::max(now_, next->at);
      auto fire = std::exchange(next->fire, nullptr);
      fire();
    }
    now_ = std::max(now_, to);
    settle();
  }
  // Runs the loop's ready handlers (the devices' jobs, their results, the gyro bus's reads).
  void settle() {
    while (io_.poll() > 0) {
    }
  }

 private:
  struct HandAlarm final : Alarm {
    HandTime& t;
    Clock::time_point at{};
    std::function<void()> fire;
    explicit HandAlarm(HandTime& time) : t(time) { t.alarms_.insert(this); }
    ~HandAlarm() override { t.alarms_.erase(this); }
    void set(Clock::time_point when, std::function<void()> f) override {
      at = when;
      fire = std::move(f);
    }
    void cancel() override { fire = nullptr; }
  };
  asio::io_context& io_;
  asio::executor_work_guard<asio::io_context::executor_type> work_;
  Clock::time_point now_ = Clock::time_point{} + std::chrono::hours(1);
  std::set<HandAlarm*> alarms_;
};

// An acquisition at a time scale of 1 (a period of 1 s, polls at t0 + k - 0.5 s) on the fake
// bench, on time by hand. The sink answers 25 degC, a run is on from the second tick, and the
// sink's call for second k takes busy[k] (the loop blocked).
struct ByHand {
  Bench bench;
  asio::io_context io;
  HandTime time{io};
  std::map<std::int64_t, std::chrono::milliseconds> busy;
  std::vector<Tick> ticks;
  std::unique_ptr<Acquisition> acq;
  LoopTime::Clock::time_point t0;

  explicit ByHand(bool paced) {
    AcquisitionOptions o;
    o.time_scale = 1.0;
    o.units = kUnits;
    o.safe_setpoint_c = 20.0;
    o.time = &time;
    TickSink sink;
    sink.on_tick = [this](std::int64_t k, const TickInput& in) {
      ticks.push_back({k, in});
      if (busy.contains(k)) time.pass(busy[k]);
      return 25.0;
    };
    sink.run_active = [this] { return !ticks.empty(); };
    acq = std::make_unique<Acquisition>(io, o, fake_devices(bench, paced), std::move(sink));
    t0 = time.now() + std::chrono::seconds(1);
    acq->start();
    time.settle();
  }
  ~ByHand() {
    acq->stop([](const std::string&) {});
    time.settle();
    acq->join();
  }
  // The loop until t0 + s seconds.
  void run_until(double s) { time.run_until(t0 + std::chrono::milliseconds(std::llround(s * 1000))); }
  const Tick& tick(std::int64_t k) const {
    REQUIRE(static_cast<std::size_t>(k) < ticks.size());
    return ticks[static_cast<std::size_t>(k)];
  }
};

// Second `k` was skipped: handed on as not read, nothing of a device in it.
void check_unread(const Tick& t) {
  INFO("skipped second " << t.k);
  CHECK(unread(t.in));
  CHECK_FALSE(t.in.chamber_c);
  CHECK_FALSE(t.in.chamber_link_down);
  for (const auto& u : t.in.units) {
    CHECK_FALSE(u.gyro_dph);
    CHECK(u.frames == 0);
    CHECK_FALSE(u.t1_c);
    CHECK_FALSE(u.t2_c);
  }
}

}  // namespace

TEST_CASE("acquisition: one TickInput per second with the fake devices' values, real clock") {
  Bench bench;
  const auto ticks = acquire(bench, false, 5);
  REQUIRE(ticks.size() == 5);
  check_consecutive(ticks);
  for (const auto& t : ticks) {
    check_values(t);
    CHECK(t.in.gyro_read);
  }
  // The safe setpoint at the bring-up, the sink's 25 degC once, the safe setpoint on the way out.
  REQUIRE(bench.written.size() == 3);
  CHECK(bench.written[0] == 20.0);
  CHECK(bench.written[1] == 25.0);
  CHECK(bench.written[2] == 20.0);
  CHECK(bench.steps == 0);  // the real clock steps no world
}

TEST_CASE("acquisition: a device's missing second is marked missing, never filled in") {
  Bench bench;
  bench.chamber_down = {3};
  bench.module_down = {3};
  bench.unit1_gyro_silent = {3};
  bench.unit1_t2_open = {4};
  const auto ticks = acquire(bench, false, 5);
  REQUIRE(ticks.size() == 5);
  check_consecutive(ticks);
  // Tick 2 (poll 3): no chamber, no module, unit 1's gyro silent; unit 0's gyro still read.
  const TickInput& gap = ticks[2].in;
  CHECK(gap.chamber_link_down);
  CHECK_FALSE(gap.chamber_c);
  CHECK_FALSE(gap.chamber_setpoint_c);
  CHECK_FALSE(gap.late);  // a device that failed, not a late loop
  for (const auto& u : gap.units) {
    CHECK_FALSE(u.t1_c);
    CHECK_FALSE(u.t2_c);
  }
  REQUIRE(gap.units[0].gyro_dph);
  CHECK(*gap.units[0].gyro_dph == Approx(3.0));
  CHECK_FALSE(gap.units[1].gyro_dph);
  CHECK(gap.units[1].frames == 0);
  // Tick 3 (read 4): only unit 1's T2 open, the rest read.
  const TickInput& open = ticks[3].in;
  REQUIRE(open.chamber_c);
  CHECK(*open.chamber_c == Approx(22.0));
  REQUIRE(open.units[1].t1_c);
  CHECK_FALSE(open.units[1].t2_c);
  CHECK_FALSE(open.units[1].out_of_range);
  REQUIRE(open.units[0].t2_c);
  CHECK(*open.units[0].t2_c == Approx(44.0));
  check_values(ticks[1]);
  check_values(ticks[4]);
}

TEST_CASE("acquisition: a chamber link lost and back, its setpoint written again once it answers") {
  Bench bench;
  bench.chamber_down = {3, 4};
  const auto ticks = acquire(bench, false, 6);
  REQUIRE(ticks.size() == 6);
  check_consecutive(ticks);
  for (std::size_t i : {2u, 3u}) {
    INFO("tick " << i);
    CHECK(ticks[i].in.chamber_link_down);
    CHECK_FALSE(ticks[i].in.chamber_c);
  }
  check_values(ticks[4]);
  check_values(ticks[5]);
  // The controller may have restarted while away: 25 degC is written again after the link is
  // back (the writes while it was down failed), not assumed. Then the safe setpoint at the end.
  REQUIRE(bench.written.size() == 4);
  CHECK(bench.written[0] == 20.0);
  CHECK(bench.written[1] == 25.0);
  CHECK(bench.written[2] == 25.0);
  CHECK(bench.written[3] == 20.0);
}

TEST_CASE("acquisition: the paced clock gives the real clock's ticks, one world step per second of a run") {
  Bench real_bench, paced_bench;
  const auto real = acquire(real_bench, false, 6);
  const auto paced = acquire(paced_bench, true, 6);
  REQUIRE(real.size() == 6);
  REQUIRE(paced.size() == 6);
  check_consecutive(paced);
  for (std::size_t i = 0; i < real.size(); ++i) {
    INFO("tick " << i);
    const TickInput& a = real[i].in;
    const TickInput& b = paced[i].in;
    check_values(paced[i]);
    CHECK(same(a.chamber_c, b.chamber_c));
    CHECK(same(a.chamber_setpoint_c, b.chamber_setpoint_c));
    CHECK(a.chamber_alarm == b.chamber_alarm);
    CHECK(a.chamber_link_down == b.chamber_link_down);
    CHECK(a.late == b.late);
    for (std::size_t u = 0; u < kUnits; ++u) {
      CHECK(same(a.units[u].gyro_dph, b.units[u].gyro_dph));
      CHECK(a.units[u].frames == b.units[u].frames);
      CHECK(same(a.units[u].t1_c, b.units[u].t1_c));
      CHECK(same(a.units[u].t2_c, b.units[u].t2_c));
    }
    // The first second comes before the run: the paced world did not step for it.
    CHECK(b.gyro_read == (i > 0));
  }
  // One step per second of the run: the jobs of ticks 1..5 (and the one after the last, which
  // may or may not have run when the loop stopped).
  CHECK(paced_bench.steps >= 5);
  CHECK(paced_bench.steps <= 6);
  CHECK(paced_bench.written == real_bench.written);
}

TEST_CASE("acquisition: a paced world that does not step leaves its second missing") {
  Bench bench;
  bench.step_fails = {2};  // the job of tick 2
  const auto ticks = acquire(bench, true, 5);
  REQUIRE(ticks.size() == 5);
  check_consecutive(ticks);
  const TickInput& gap = ticks[2].in;
  CHECK(gap.chamber_link_down);
  CHECK_FALSE(gap.chamber_c);
  CHECK_FALSE(gap.gyro_read);
  for (const auto& u : gap.units) {
    CHECK_FALSE(u.t1_c);
    CHECK_FALSE(u.t2_c);
  }
  check_values(ticks[1]);
  check_values(ticks[3]);
}

TEST_CASE("acquisition: the gyro transport's stream problems reach the seconds, each kind once, not every second") {
  Bench bench;
  // Garbage reported with every second's frames, a CRC error once: within a minute each kind is
  // handed on (and logged) once; the numbers in a message do not make it another kind.
  for (int n = 1; n <= 6; ++n) bench.stream_news[n] = {"fake0: " + std::to_string(n * 3) + " bytes of garbage before a sync word"};
  bench.stream_news[3].push_back("fake0: frame at byte 900: bad CRC");
  const auto ticks = acquire(bench, false, 6);
  REQUIRE(ticks.size() == 6);
  std::vector<std::string> handed;
  for (const auto& t : ticks) handed.insert(handed.end(), t.in.gyro_stream_events.begin(), t.in.gyro_stream_events.end());
  REQUIRE(handed.size() == 2);
  CHECK(handed[0] == "fake0: 3 bytes of garbage before a sync word");
  CHECK(handed[1] == "fake0: frame at byte 900: bad CRC");
  // The frames themselves are unaffected.
  for (const auto& t : ticks) check_values(t);
}

TEST_CASE("acquisition: news the transport has at a sample's close reaches that very second, with nothing to read") {
  Bench bench;
  bench.news_at_close = 3;  // the third close: tick 2's
  const auto ticks = acquire(bench, false, 6);
  REQUIRE(ticks.size() == 6);
  for (std::size_t i = 0; i < ticks.size(); ++i) {
    INFO("tick " << i);
    if (i == 2) {
      REQUIRE(ticks[i].in.gyro_stream_events.size() == 1);
      CHECK(ticks[i].in.gyro_stream_events[0] == "fake0: dead_line: no byte received in 3 sample periods");
    } else {
      CHECK(ticks[i].in.gyro_stream_events.empty());
    }
  }
}

TEST_CASE("acquisition by hand: the real clock late catches up, far behind skips ahead, each second exact") {
  ByHand h(false);
  h.busy[1] = std::chrono::seconds(3);   // the loop back at t0 + 4 s: 5 half-periods behind
  h.busy[5] = std::chrono::seconds(12);  // the loop back at t0 + 17 s: 23 half-periods behind
  h.run_until(20.5);                     // up to the poll for second 21 (poll 11)
  // A loop blocked between a poll and its tick: tick 21, due at t0 + 21 s, is woken 10.5 s late.
  h.time.pass(std::chrono::milliseconds(11000));
  h.run_until(32.0);

  REQUIRE(h.ticks.size() == 33);
  check_consecutive(h.ticks);
  // Seconds 0 and 1 on time; 2, 3 and 4 caught up at t0 + 4 s, each polled late but before its
  // tick, with its own poll (3, 4, 5); 5 on time.
  for (std::int64_t k = 0; k <= 5; ++k) check_values(h.tick(k), k + 1);
  // The poll for second 6 (due t0 + 5.5 s) woke at t0 + 17 s, 23 half-periods behind: 22 skipped,
  // seconds 6..16 not read and no device polled for them; second 17 read poll 7, on time.
  for (std::int64_t k = 6; k <= 16; ++k) check_unread(h.tick(k));
  for (std::int64_t k = 17; k <= 20; ++k) check_values(h.tick(k), k - 10);
  // Tick 21 woke 21 half-periods behind: 20 skipped, seconds 21..30 not read; second 31 closes
  // with the poll made for second 21 (poll 11), then second 32 is polled and read on time.
  for (std::int64_t k = 21; k <= 30; ++k) check_unread(h.tick(k));
  check_values(h.tick(31), 11);
  check_values(h.tick(32), 12);
  {
    std::lock_guard lock(h.bench.m);
    CHECK(h.bench.chamber_polls == 12);
    CHECK(h.bench.coil_reads == 12);
  }
  const AcquisitionStats st = h.acq->stats();
  CHECK(st.ticks == 12);
  CHECK(st.ticks_skipped == 21);
  CHECK(st.polls_late == 0);
  CHECK(st.tick_late_max_s == Approx(2.0));  // tick 2, due t0 + 2 s, closed at t0 + 4 s
  CHECK(st.tick_late_s == Approx(0.0));      // tick 32 on time
}

TEST_CASE("acquisition by hand: the paced clock late moves its schedule back, no second skipped") {
  ByHand h(true);
  h.busy[1] = std::chrono::seconds(5);  // the loop back at t0 + 6 s: tick 2 four seconds late
  h.run_until(4.0);
  // Not yet at t0 + 6 s: seconds 0 and 1 only.
  REQUIRE(h.ticks.size() == 2);
  h.run_until(10.0);
  // t0 moved 4 s forward at tick 2's asking: ticks 2..6 at old t0 + 6..10 s, each on time.
  REQUIRE(h.ticks.size() == 7);
  check_consecutive(h.ticks);
  for (const auto& t : h.ticks) check_values(t);
  for (std::size_t k = 0; k < h.ticks.size(); ++k) CHECK(h.ticks[k].in.gyro_read == (k > 0));
  const AcquisitionStats st = h.acq->stats();
  CHECK(st.ticks_skipped == 0);
  CHECK(st.paced_slowed == 1);
  CHECK(st.tick_late_max_s == Approx(0.0));
  std::lock_guard lock(h.bench.m);
  CHECK(h.bench.steps == 7);          // the jobs of seconds 1..7 (a run from the second tick)
  CHECK(h.bench.chamber_polls == 8);  // seconds 0..6, and the job of second 7 already done
}
