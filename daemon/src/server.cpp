// The Asio server of fogbenchd. Everything runs on one io_context thread except the chamber and
// thermistor I/O: libmodbus only has blocking calls, so those run on a worker thread (its own
// io_context used as a job queue) that posts each result back to the loop; and the analysis
// (fits, verifications, the workbench, large reads), which runs on a second worker with its own
// read connection to the store and posts its replies back; and the commit of each second's
// samples, on a writer thread with a write connection of its own (sample_writer.hpp), so no
// fsync holds the loop (docs/daemon.md, "Threads"). The other writes to the store (states,
// events, models, plans) stay on the loop thread: a Store is single-threaded. Sessions take
// turns on the loop (Turns), so no number of clients can hold it.
//
// Its rooms: a session and the turns (session.hpp), the analysis worker (analysis_worker.hpp),
// the sample writer (sample_writer.hpp), the loop's scheduler slice (scheduling.hpp), and here
// Server::Impl, the one object that owns the io_context, the signal set, the acceptors, the set
// of sessions, the acquisition schedule and the device workers, as in Asio's example servers.
// Why this file is longer than 800 lines: its one job is that owner. Impl's handlers (accept,
// tick, poll, stop) share its state and its order of shutdown; split further they would pass
// Impl's internals between files instead of keeping one owner.
#include "fogbench/daemon/server.hpp"
#include "fogbench/daemon/plan_runner.hpp"
#include "fogbench/signing/signing.hpp"

#include <grp.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include <boost/asio.hpp>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <deque>
#include <iostream>
#include <list>
#include <thread>

#include <spdlog/spdlog.h>

#include "fogbench/protocol/framing.hpp"
#include "fogbench/daemon/handler.hpp"
#include "fogbench/daemon/instance.hpp"
#include "fogbench/daemon/metrics.hpp"
#include "fogbench/daemon/station.hpp"
#include "fogbench/daemon/systemd.hpp"
#include "fogbench/drivers/chamber.hpp"
#include "fogbench/drivers/chamber_registry.hpp"
#include "fogbench/drivers/gyro_bus.hpp"
#include "fogbench/drivers/thermistor_module.hpp"
#include "fogbench/daemon/run_identity.hpp"
#include "fogbench/daemon/scheduling.hpp"
#include "analysis_worker.hpp"
#include "notify_status.hpp"
#include "plant_link.hpp"
#include "session.hpp"
#include "sim_clock.hpp"
#include "web_server.hpp"

namespace fogbench::daemon {

namespace asio = boost::asio;
using nlohmann::json;
using Clock = std::chrono::steady_clock;
using namespace net;

namespace {

// An accept that fails for want of descriptors or memory (EMFILE, ENFILE, ENOBUFS, ENOMEM)
// would fail again at once, the connection still waiting in the backlog: wait this long first.
constexpr auto kAcceptBackoff = std::chrono::milliseconds(250);
// Failed accepts are logged at most this often, with how many there were.
constexpr auto kAcceptLogEvery = std::chrono::seconds(60);
// The chamber is sent to its safe setpoint on the way out; this long at most.
constexpr auto kShutdownDeadline = std::chrono::seconds(5);

// Whether an accept failed for want of resources, so retrying at once would spin.
bool accept_starved(const boost::system::error_code& ec) {
  const int v = ec.value();
  return ec.category() == boost::system::system_category() &&
         (v == EMFILE || v == ENFILE || v == ENOBUFS || v == ENOMEM);
}

// What the worker read from the chamber and the thermistor module at one poll.
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

}  // namespace

struct Server::Impl {
  DaemonConfig config;
  ServerOptions options;
  asio::io_context io;
  asio::signal_set signals{io, SIGTERM, SIGINT};
  std::optional<asio::local::stream_protocol::acceptor> unix_acceptor;
  std::optional<asio::ip::tcp::acceptor> tcp_acceptor;
  std::list<std::weak_ptr<SessionBase>> sessions;
  // One daemon per store and per socket path (instance.hpp).
  std::optional<StoreLock> store_lock;
  SocketFileId socket_id;
  // Failed accepts: the backoff timers and the rate-limited log.
  asio::steady_timer unix_accept_retry{io};
  asio::steady_timer tcp_accept_retry{io};
  std::uint64_t accept_failures = 0;  // since the last log line
  std::optional<Clock::time_point> accept_logged;

  std::optional<storage::Store> store;
  std::unique_ptr<Station> station;
  std::unique_ptr<Handler> handler;
  std::unique_ptr<PlanRunner> plans;  // qualification plans (plan_runner.hpp), told after each tick
  std::unique_ptr<StatusNotifier> notifier;  // systemd's STATUS= line, under systemd (notify_status.hpp)
  Turns turns{io};
  // Fits, verifications and large reads (offload.hpp); declared after the station so that it
  // stops (joins) before the station goes.
  std::unique_ptr<AnalysisWorker> analysis;
  // The plant store's replication (plant_link.hpp), when configured.
  std::unique_ptr<PlantLink> plant;
  // Each second's samples, committed on a thread of their own (sample_writer.hpp); declared after
  // the station, so it stops (commits what it holds, joins) before the station goes.
  std::unique_ptr<ThreadedSampleWriter> samples;

  // The worker: a job queue on its own thread. The chamber and module are touched only there.
  asio::io_context wio;
  std::optional<asio::executor_work_guard<asio::io_context::executor_type>> wguard;
  std::thread wthread;
  std::unique_ptr<drivers::Chamber> chamber;
  std::unique_ptr<drivers::ThermistorSource> thermistors;
  // The thermistor module's own worker (polls only; with the shared simulated clock the
  // module is read on the worker above, in the job of each second, and this one stays idle).
  asio::io_context tio;
  std::optional<asio::executor_work_guard<asio::io_context::executor_type>> tguard;
  std::thread tthread;

  // The gyro bus: read on the loop through its fd.
  std::optional<drivers::GyroBus> bus;
  asio::posix::stream_descriptor gyro_sd{io};
  asio::steady_timer gyro_retry{io};
  std::vector<::can_frame> frames;
  bool gyro_logged_down = false;

  // The acquisition schedule: half-period slots from t0; even slots close a sample, odd slots
  // poll the Modbus devices, so the temperatures are read mid-way through the gyro's averaging
  // window and are fresh at the next tick.
  asio::steady_timer timer{io};
  Clock::time_point t0;
  std::int64_t slot = 0;
  std::chrono::nanoseconds half_period{};
  bool chamber_in_flight = false, coils_in_flight = false;  // a poll of the device is under way
  // The latest reading: its chamber part and its thermistor part arrive separately (a stalled
  // module does not hold up the chamber's value), each with its own freshness.
  std::optional<DeviceReading> reading;
  bool have_chamber = false, have_coils = false;  // each part arrived at least once
  bool new_chamber = false, new_coils = false;    // arrived since the last tick
  int stale_chamber = 0, stale_coils = 0;         // ticks since a new part was used
  std::int64_t late_polls = 0;           // ticks that used the previous period's reading
  std::optional<double> written_setpoint_c;
  bool write_in_flight = false;
  // For the metrics (web_metrics.cpp): seconds acquired, skipped, and how late the ticks ran.
  std::int64_t ticks_done = 0, ticks_skipped = 0;
  double tick_late_s = 0.0, tick_late_max_s = 0.0;
  void note_lateness(Clock::time_point due) {
    ++ticks_done;
    tick_late_s = std::max(0.0, std::chrono::duration<double>(Clock::now() - due).count());
    tick_late_max_s = std::max(tick_late_max_s, tick_late_s);
  }
  // The web panel and metrics (web.hpp), when configured.
  std::unique_ptr<web::WebServer> web;

  // The shared simulated clock (config.sim_clock, fogbench-sim --paced): the daemon paces the
  // world. Second k is acquired once a worker job has written the setpoint of tick k-1, asked
  // the bench to step one second (so its frames are in the gyro socket) and polled the devices;
  // tick k waits for that job rather than its wall time alone, so a busy host slows the run
  // down instead of skipping seconds. The world moves only for seconds of a run.
  struct PacedResult {
    DeviceReading reading;
    bool asked = false;     // the job asked the bench to step (a run was active)
    bool advanced = false;  // and it did: the world stepped one second for this tick
  };
  std::unique_ptr<SimClock> sim_clock;         // used on the worker only
  std::optional<PacedResult> paced_result;     // the job of second paced_k, once done
  std::int64_t paced_k = 0;                    // the second the next tick closes
  std::chrono::nanoseconds period{};
  bool paced_waiting = false;                  // the tick was due before its job was done
  std::int64_t paced_slowed = 0;               // ticks the schedule was moved back for
  Clock::time_point paced_logged{};
  bool clock_logged_down = false;
  double commanded_setpoint_c = 0.0;           // the station's last output

  bool stopping = false;
  asio::steady_timer shutdown_timer{io};
  int exit_code = 0;

  Impl(DaemonConfig c, ServerOptions o) : config(std::move(c)), options(o) {}

  // --- command socket
  template <class Socket>
  void accept_session(Socket socket, std::string peer, bool may_control) {
    std::string user;
    if constexpr (std::is_same_v<Socket, asio::local::stream_protocol::socket>) user = peer_user_name(socket.native_handle());
    auto s = std::make_shared<Session<Socket>>(std::move(socket), *handler, turns, peer, may_control,
                                               may_control ? std::string() : config.socket.tcp_token);
    s->set_peer_user(std::move(user));
    sessions.remove_if([](const auto& w) { return w.expired(); });
    sessions.push_back(s);
    s->set_idle_timeout(config.socket.idle_timeout_s);
    s->start();
  }

  // Connections open now, both sockets together.
  std::size_t open_sessions() {
    sessions.remove_if([](const auto& w) {
      auto s = w.lock();
      return !s || s->is_closed();
    });
    return sessions.size();
  }

  // Connections open now, every transport: the sockets' and the WebSockets' sessions, and the
  // web side's HTTP connections. What socket.max_clients limits.
  std::size_t open_clients() { return open_sessions() + (web ? web->open_http() : 0); }

  // A new connection: a session, or a refusal past socket.max_clients.
  template <class Socket>
  void admit(Socket socket, std::string peer, bool may_control) {
    const std::size_t open = open_clients();
    if (open >= static_cast<std::size_t>(config.socket.max_clients)) {
      spdlog::warn("client {}: {} clients connected (socket.max_clients); refused", peer, open);
      refuse(std::move(socket), "too many clients (" + std::to_string(open) +
                                    " connected, socket.max_clients); closing");
      return;
    }
    accept_session(std::move(socket), std::move(peer), may_control);
  }

  // A failed accept. Out of descriptors or memory, the next accept would fail at once (the
  // client still waits in the backlog): retry after kAcceptBackoff instead of spinning. Logged
  // at most once every kAcceptLogEvery, with the count.
  void accept_failed(const char* which, const boost::system::error_code& ec, asio::steady_timer& retry,
                     void (Impl::*again)()) {
    ++accept_failures;
    const auto now = Clock::now();
    if (!accept_logged || now - *accept_logged >= kAcceptLogEvery) {
      spdlog::warn("accept on {}: {} ({} failed accepts since the last report; {})", which, ec.message(),
                   accept_failures,
                   accept_starved(ec) ? "retrying every 250 ms; raise LimitNOFILE or lower socket.max_clients"
                                      : "retrying");
      accept_logged = now;
      accept_failures = 0;
    }
    if (!accept_starved(ec)) {
      (this->*again)();
      return;
    }
    retry.expires_after(kAcceptBackoff);
    retry.async_wait([this, again](boost::system::error_code e) {
      if (!e && !stopping) (this->*again)();
    });
  }

  void accept_unix() {
    unix_acceptor->async_accept([this](boost::system::error_code ec, asio::local::stream_protocol::socket s) {
      if (stopping || ec == asio::error::operation_aborted) return;
      if (ec) return accept_failed("the unix socket", ec, unix_accept_retry, &Impl::accept_unix);
      admit(std::move(s), "unix", true);
      accept_unix();
    });
  }

  void accept_tcp() {
    tcp_acceptor->async_accept([this](boost::system::error_code ec, asio::ip::tcp::socket s) {
      if (stopping || ec == asio::error::operation_aborted) return;
      if (ec) return accept_failed("tcp", ec, tcp_accept_retry, &Impl::accept_tcp);
      boost::system::error_code e2;
      auto ep = s.remote_endpoint(e2);
      admit(std::move(s), e2 ? std::string("tcp") : ep.address().to_string() + ":" + std::to_string(ep.port()), false);
      accept_tcp();
    });
  }

  void publish(const json& message) {
    auto line = wire(message);
    for (auto it = sessions.begin(); it != sessions.end();) {
      if (auto s = it->lock()) {
        s->push(line);
        ++it;
      } else {
        it = sessions.erase(it);
      }
    }
    if (message.value("type", "") == "event") spdlog::info("event: {}", *line);
  }

  // --- worker jobs
  void post_write_setpoint(double sp_c) {
    if (write_in_flight) return;  // the next tick retries with the then-current setpoint
    write_in_flight = true;
    asio::post(wio, [this, sp_c] {
      auto r = chamber->write_setpoint_c(sp_c);
      std::string err = r ? "" : r.error().to_string();
      asio::post(io, [this, sp_c, err] {
        write_in_flight = false;
        if (err.empty()) {
          written_setpoint_c = sp_c;
        } else {
          spdlog::warn("setpoint {} C not written: {}", sp_c, err);
        }
      });
    });
  }

  // The chamber on the worker, the module on its own thread: a stalled module (or chamber)
  // must not make the other's readings late. A device whose last poll is still blocked in
  // libmodbus is not asked again.
  void post_poll() {
    if (!chamber_in_flight) {
      chamber_in_flight = true;
      asio::post(wio, [this] {
        DeviceReading c;
        read_chamber(c);
        asio::post(io, [this, c = std::move(c)] {
          chamber_in_flight = false;
          take_chamber(c);
        });
      });
    }
    if (!coils_in_flight) {
      coils_in_flight = true;
      asio::post(tio, [this] {
        DeviceReading t;
        read_thermistors(t);
        asio::post(io, [this, t = std::move(t)] {
          coils_in_flight = false;
          take_thermistors(t);
        });
      });
    }
  }

  // On the worker: one poll of the chamber and the thermistor module.
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
    d.coils.resize(config.drivers.units.size());
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
  void take_reading(const DeviceReading& d) {
    take_chamber(d);
    take_thermistors(d);
  }

  // --- gyro bus
  std::vector<drivers::GyroChannelConfig> gyro_channels() const {
    std::vector<drivers::GyroChannelConfig> g;
    for (const auto& u : config.drivers.units) g.push_back(u.gyro);
    return g;
  }

  void open_gyro() {
    if (stopping) return;
    drivers::Result<void> ok;
    if (!bus) {
      auto b = drivers::GyroBus::open(config.drivers.gyro_bus, gyro_channels());
      if (b) bus.emplace(std::move(*b));
      else ok = std::unexpected(b.error());
    } else {
      ok = bus->reopen(config.drivers.gyro_bus);
    }
    if (!ok) {
      if (!gyro_logged_down) spdlog::warn("gyro bus: {}; retrying every second of run time", ok.error().to_string());
      gyro_logged_down = true;
      gyro_retry.expires_after(gyro_retry_delay(options.time_scale));
      gyro_retry.async_wait([this](boost::system::error_code ec) {
        if (!ec) open_gyro();
      });
      return;
    }
    gyro_logged_down = false;
    spdlog::info("gyro bus: {}", bus->transport().describe());
    boost::system::error_code ec;
    gyro_sd.assign(bus->fd(), ec);
    if (ec) spdlog::error("gyro bus fd: {}", ec.message());
    wait_gyro();
  }

  void wait_gyro() {
    gyro_sd.async_wait(asio::posix::stream_descriptor::wait_read, [this](boost::system::error_code ec) {
      if (ec || stopping) return;
      // Bounded per turn so a flood of frames cannot starve the sockets and the schedule.
      for (int i = 0; i < 16; ++i) {
        auto n = bus->read_frames(frames);
        if (!n) {
          spdlog::warn("gyro bus: {}", n.error().to_string());
          (void)gyro_sd.release();  // the bus owns and closes the fd
          gyro_retry.expires_after(gyro_retry_delay(options.time_scale));
          gyro_retry.async_wait([this](boost::system::error_code e) {
            if (!e) open_gyro();
          });
          return;
        }
        if (*n == 0) break;
      }
      wait_gyro();
    });
  }

  // --- acquisition schedule
  void schedule() {
    // Absolute deadlines, t0 + slot * half_period: a late wake-up never shifts the next one.
    timer.expires_at(t0 + slot * half_period);
    timer.async_wait([this](boost::system::error_code ec) {
      if (ec || stopping) return;
      on_slot();
    });
  }

  void on_slot() {
    const auto now = Clock::now();
    // Far behind (the loop was blocked, e.g. by a long fit): skip ahead rather than replay a
    // burst of empty seconds.
    const auto behind = (now - (t0 + slot * half_period)) / half_period;
    if (behind > 20) {
      spdlog::warn("acquisition {} half-periods late; skipping ahead", behind);
      // The seconds skipped are still seconds of the run: they are stored as not read
      // (flagged missing), so a run has every second of its clock and the count of its samples
      // says how long it ran. Measured by scripts/soak: holes appeared here at 500x.
      const std::int64_t to = slot + (behind & ~std::int64_t{1});
      for (std::int64_t s = slot; s < to; ++s)
        if (s % 2 == 0) tick_unread(s / 2);
      slot = to;
    }
    if (slot % 2 != 0) {  // odd, including the first slot, -1
      post_poll();
    } else {
      note_lateness(t0 + slot * half_period);
      tick(slot / 2);
    }
    ++slot;
    schedule();
  }

  // A second the loop was too late to acquire: nothing read, the profile steps on.
  void tick_unread(std::int64_t k) {
    ++ticks_skipped;
    TickInput in = new_input();
    in.late = true;
    in.gyro_read = false;  // its frames go into the next period's sample
    const TickOutput out = station->tick(static_cast<double>(k), in);
    if (!written_setpoint_c || *written_setpoint_c != out.setpoint_c) post_write_setpoint(out.setpoint_c);
  }

  // The gyro's averages since the last tick.
  void fill_gyro(TickInput& in) {
    in.gyro_read = bus && gyro_sd.is_open();
    if (!bus) return;
    auto s = bus->close_samples();
    for (std::size_t i = 0; i < s.units.size() && i < in.units.size(); ++i) {
      in.units[i].gyro_dph = s.units[i].rate_dph;
      in.units[i].frames = s.units[i].frames;
      in.units[i].frames_lost = s.units[i].frames_lost;
      in.units[i].frames_corrupt = s.units[i].frames_corrupt;
    }
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
      in.units[i].out_of_range = d.coils[i].out_of_range;
    }
  }
  TickInput new_input() const {
    TickInput in;
    in.wall_time = std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
    in.units.resize(config.drivers.units.size());
    return in;
  }

  void tick(std::int64_t k) {
    TickInput in = new_input();
    fill_gyro(in);
    // The poll of this period normally arrived half a period ago. When a part of it is late (a
    // loaded machine at a high time scale, a stalled device), the previous one, one period old,
    // stands in once: a settle judged on "every reading in band" would otherwise restart at
    // each late poll. Older than that, its values are missing, and the station is told the
    // loop was late for them (a run that fails says so).
    auto usable = [&](bool have, bool& fresh, int& stale) {
      if (!have) return false;
      if (fresh) {
        fresh = false;
        stale = 0;
        return true;
      }
      if (stale++ < 1) {
        ++late_polls;
        return true;
      }
      return false;
    };
    if (usable(have_chamber, new_chamber, stale_chamber)) {
      fill_chamber(in, *reading);
    } else if (have_chamber) {
      in.chamber_link_down = !reading->chamber_ok;
      in.late = true;
    }
    if (usable(have_coils, new_coils, stale_coils)) fill_coils(in, *reading);
    else if (have_coils) in.late = true;
    const TickOutput out = station->tick(static_cast<double>(k), in);
    commanded_setpoint_c = out.setpoint_c;
    if (!written_setpoint_c || *written_setpoint_c != out.setpoint_c) post_write_setpoint(out.setpoint_c);
  }

  // --- the shared simulated clock (config.sim_clock)
  void paced_start() {
    period = 2 * half_period;
    t0 = Clock::now() + period;
    paced_k = 0;
    commanded_setpoint_c = config.safe_setpoint_c;
    paced_post_job(false, std::nullopt);
    paced_schedule();
  }

  // The job of second paced_k: the setpoint of the last tick, one simulated second (in a run),
  // then the poll. In this order on the worker, so the world steps under the setpoint the
  // station commanded and the poll reads the end of that second.
  void paced_post_job(bool advance, std::optional<double> setpoint_c) {
    asio::post(wio, [this, advance, setpoint_c] {
      PacedResult r;
      r.asked = advance;
      std::string write_error, clock_error;
      if (setpoint_c)
        if (auto w = chamber->write_setpoint_c(*setpoint_c); !w) write_error = w.error().to_string();
      if (advance) {
        if (auto t = sim_clock->advance(1)) r.advanced = true;
        else clock_error = t.error();
      }
      r.reading = read_devices();
      if (!clock_error.empty()) {
        // The bench did not move: nothing of this second was read. As a bench that does not
        // answer, the chamber counts as unreachable (link_loss decides).
        r.reading = DeviceReading{};
        r.reading.coils.resize(config.drivers.units.size());
        r.reading.chamber_error = r.reading.thermistor_error = "simulated clock: " + clock_error;
      }
      asio::post(io, [this, setpoint_c, write_error, clock_error, r = std::move(r)]() mutable {
        if (setpoint_c) {
          if (write_error.empty()) written_setpoint_c = *setpoint_c;
          else spdlog::warn("setpoint {} C not written: {}", *setpoint_c, write_error);
        }
        if (!clock_error.empty()) {
          if (!clock_logged_down) spdlog::error("simulated clock: {}", clock_error);
          clock_logged_down = true;
        } else if (r.advanced && clock_logged_down) {
          spdlog::info("simulated clock: stepping again");
          clock_logged_down = false;
        }
        paced_result = std::move(r);
        if (paced_waiting && !stopping) {
          paced_waiting = false;
          paced_tick();
        }
      });
    });
  }

  void paced_schedule() {
    timer.expires_at(t0 + paced_k * period);
    timer.async_wait([this](boost::system::error_code ec) {
      if (ec || stopping) return;
      if (paced_result) paced_tick();
      else paced_waiting = true;  // the job's completion ticks
    });
  }

  void paced_tick() {
    PacedResult r = std::move(*paced_result);
    paced_result.reset();
    note_lateness(t0 + paced_k * period);
    const std::int64_t k = paced_k++;
    // Every frame of the second the bench stepped is in the socket: read them all now.
    if (bus && gyro_sd.is_open())
      for (int i = 0; i < 1000; ++i) {
        auto n = bus->read_frames(frames);
        if (!n || *n == 0) break;
      }
    TickInput in = new_input();
    fill_gyro(in);
    in.gyro_read = in.gyro_read && r.advanced;  // a world that did not step sent nothing
    if (!r.asked && station->active_run_id()) {
      // A run was asked for after this second's job was sent, so the world did not move for
      // it: its first second is the next, one the world steps through. A run's samples then
      // depend on the seed and the runs before it, not on when it was started.
    } else {
      take_reading(r.reading);
      new_chamber = new_coils = false;
      fill_chamber(in, r.reading);
      fill_coils(in, r.reading);
      commanded_setpoint_c = station->tick(static_cast<double>(k), in).setpoint_c;
    }
    std::optional<double> sp;
    if (!written_setpoint_c || *written_setpoint_c != commanded_setpoint_c) sp = commanded_setpoint_c;
    paced_post_job(station->active_run_id().has_value(), sp);
    // Behind the schedule by more than two periods (the host is busy): the schedule moves back
    // rather than catching up in a burst. The run goes on slower than the time scale, and every
    // second is acquired as it would be on an idle host.
    const auto now = Clock::now();
    const auto due = t0 + paced_k * period;
    if (now - due > 2 * period) {
      t0 += now - due;
      ++paced_slowed;
      if (now - paced_logged > std::chrono::seconds(10)) {
        paced_logged = now;
        spdlog::info("simulated clock: slower than time scale {} (a busy host); {} tick(s) waited so far",
                     options.time_scale, paced_slowed);
      }
    }
    paced_schedule();
  }

  // --- the web side: GET /metrics
  std::string metrics() {
    MetricsInput in;
    in.status = station->status();
    if (config.storage_path != ":memory:") {
      std::int64_t bytes = 0;
      for (const char* suffix : {"", "-wal", "-shm"}) {
        std::error_code ec;
        const auto n = std::filesystem::file_size(config.storage_path.string() + suffix, ec);
        if (!ec) bytes += static_cast<std::int64_t>(n);
      }
      in.store_bytes = bytes;
    }
    in.web_clients = web ? web->open_websockets() + web->open_http() : 0;
    const std::size_t all = open_sessions();
    const std::size_t ws = web ? web->open_websockets() : 0;
    in.socket_clients = all >= ws ? all - ws : 0;
    in.http_requests = web ? web->requests() : 0;
    in.ticks = ticks_done;
    in.ticks_skipped = ticks_skipped;
    in.polls_late = late_polls;
    in.paced_slowed = paced_slowed;
    in.tick_lateness_s = tick_late_s;
    in.tick_lateness_max_s = tick_late_max_s;
    return render_metrics(in);
  }

  // --- stopping
  void begin_stop(const std::string& why) {
    if (stopping) return;
    stopping = true;
    // systemd hears it before the shutdown work (the run's end, the safe setpoint) begins.
    systemd::notify("STOPPING=1\nSTATUS=stopping: " + why);
    if (notifier) notifier->stop();
    spdlog::info("stopping: {}", why);
    station->shutdown("fogbenchd stopping: " + why);
    boost::system::error_code ec;
    timer.cancel();
    gyro_retry.cancel();
    unix_accept_retry.cancel();
    tcp_accept_retry.cancel();
    signals.cancel();
    if (unix_acceptor) unix_acceptor->close(ec);
    if (tcp_acceptor) tcp_acceptor->close(ec);
    if (web) web->stop();
    for (auto& w : sessions)
      if (auto s = w.lock()) s->close();
    sessions.clear();
    if (gyro_sd.is_open()) (void)gyro_sd.release();
    // The last job: the safe setpoint. Its completion, or the deadline, ends the loop.
    const double safe = config.safe_setpoint_c;
    shutdown_timer.expires_after(kShutdownDeadline);
    shutdown_timer.async_wait([this](boost::system::error_code e) {
      if (!e) {
        spdlog::error("the chamber did not confirm the safe setpoint within the deadline");
        exit_code = 1;
        io.stop();
      }
    });
    asio::post(wio, [this, safe] {
      auto r = chamber->write_setpoint_c(safe);
      std::string err = r ? "" : r.error().to_string();
      asio::post(io, [this, safe, err] {
        if (err.empty()) spdlog::info("chamber left at the safe setpoint {} C", safe);
        else {
          spdlog::error("safe setpoint {} C not written: {}", safe, err);
          exit_code = 1;
        }
        shutdown_timer.cancel();
        io.stop();
      });
    });
  }
};

Server::Server(DaemonConfig config, ServerOptions options)
    : impl_(std::make_unique<Impl>(std::move(config), options)) {}

Server::~Server() {
  if (impl_ && impl_->analysis) impl_->analysis->stop();
  if (impl_ && impl_->samples) impl_->samples->stop();
  if (impl_ && impl_->wthread.joinable()) {
    impl_->wguard.reset();
    impl_->wio.stop();
    impl_->wthread.join();
  }
  if (impl_ && impl_->tthread.joinable()) {
    impl_->tguard.reset();
    impl_->tio.stop();
    impl_->tthread.join();
  }
  // Only the socket file this daemon bound: another daemon's is never removed.
  if (impl_ && impl_->unix_acceptor) remove_if_ours(impl_->config.socket.unix_path, impl_->socket_id);
}

std::expected<void, Server::StartError> Server::start() {
  Impl& m = *impl_;
  auto fail = [](std::string message, int code = 1) { return std::unexpected(StartError{std::move(message), code}); };

  // One daemon per store: taken before anything else, so a second daemon on the same store
  // exits without marking the first one's live run interrupted (issue 11).
  if (m.config.storage_path != ":memory:") {
    auto lock = StoreLock::acquire(m.config.storage_path);
    if (!lock) return fail("storage: " + lock.error().message, lock.error().held_by_other ? 2 : 1);
    m.store_lock.emplace(std::move(*lock));
  }

  // The command socket, mode 0660: the group of the socket is the operators' group. A socket
  // another daemon answers on is never taken over; a stale one (a crash) is replaced. The
  // umask is set for the bind alone, so the socket never exists with a looser mode (no other
  // thread runs yet).
  const auto& path = m.config.socket.unix_path;
  if (auto ok = make_dirs(path.parent_path()); !ok) return fail("socket " + path.string() + ": " + ok.error());
  if (auto ok = clear_stale_socket(path); !ok) return fail(ok.error().message, ok.error().held_by_other ? 2 : 1);
  {
    const ::mode_t old_mask = ::umask(0117);
    try {
      m.unix_acceptor.emplace(m.io, asio::local::stream_protocol::endpoint(path.string()));
    } catch (const boost::system::system_error& e) {
      ::umask(old_mask);
      return fail("socket " + path.string() + ": " + e.what());
    }
    ::umask(old_mask);
  }
  m.socket_id = socket_file_id(path);
  if (::chmod(path.c_str(), 0660) != 0) spdlog::warn("chmod 0660 {}: {}", path.string(), std::strerror(errno));
  if (m.config.socket.group) {
    const ::group* g = ::getgrnam(m.config.socket.group->c_str());
    if (!g) return fail("socket.group: no such group: " + *m.config.socket.group);
    if (::chown(path.c_str(), static_cast<uid_t>(-1), g->gr_gid) != 0)
      return fail("socket.group: chown " + path.string() + " to " + *m.config.socket.group + ": " +
                  std::strerror(errno));
  }
  if (m.config.socket.tcp_port) {
    try {
      m.tcp_acceptor.emplace(m.io, asio::ip::tcp::endpoint(asio::ip::make_address(m.config.socket.tcp_address),
                                                            *m.config.socket.tcp_port));
    } catch (const boost::system::system_error& e) {
      return fail("socket tcp " + m.config.socket.tcp_address + ":" + std::to_string(*m.config.socket.tcp_port) +
                  ": " + e.what());
    }
  }

  storage::OpenOptions so;
  so.synchronous_full = m.config.storage_synchronous_full;
  so.size_limit_bytes = m.config.storage_size_limit_bytes;
  so.file_mode = kStoreFileMode;
  auto store = storage::Store::open(m.config.storage_path, so);
  if (!store) return fail("storage: " + store.error().message);
  m.store.emplace(std::move(*store));
  m.station = std::make_unique<Station>(m.config, *m.store, m.options.time_scale);
  // The station's signing key, made at the first start (docs/daemon.md "The station key"); one
  // unsafe or unreadable is refused: exit 2 naming its path.
  if (!m.config.signing_key_path.empty()) {
    auto key = signing::load_or_create(m.config.signing_key_path);
    if (!key) return fail(key.error(), 2);
    if (key->created)
      spdlog::info("signing key created: {} (public key {}, key id {})", m.config.signing_key_path.string(),
                   signing::public_path_of(m.config.signing_key_path).string(), key->key.key_id());
    m.station->set_signing_key(std::move(key->key), m.config.signing_key_path);
  }
  m.handler = std::make_unique<Handler>(*m.station);
  if (m.config.web) {
    web::WebServer::Hooks hooks;
    hooks.full = [&m] { return m.open_clients() >= static_cast<std::size_t>(m.config.socket.max_clients); };
    hooks.admit = [&m](const std::shared_ptr<SessionBase>& s) { m.sessions.push_back(s); };
    hooks.metrics = [&m] { return m.metrics(); };
    const std::string& token = m.config.web->token.empty() ? m.config.socket.tcp_token : m.config.web->token;
    m.web = std::make_unique<web::WebServer>(m.io, *m.handler, *m.config.web, token, std::move(hooks));
    if (auto ok = m.web->bind(); !ok) return fail(ok.error());
  }
  m.plans = std::make_unique<PlanRunner>(*m.station);
  m.station->set_plan_runner(m.plans.get());
  // The analysis worker reads through its own connection (WAL: beside the loop's writes). A
  // store it cannot open (":memory:") leaves the analysis on the loop, as before issue 11.
  {
    storage::OpenOptions ro;
    ro.read_only = true;
    ro.create = false;
    if (auto reader = storage::Store::open(m.config.storage_path, ro); reader && m.config.storage_path != ":memory:") {
      m.analysis = std::make_unique<AnalysisWorker>(m.io, std::move(*reader));
      m.station->set_offload(m.analysis.get());
    } else {
      spdlog::warn("storage: no read connection for the analysis worker ({}); fits and large reads run on the loop",
                   reader ? "in-memory store" : reader.error().message);
    }
  }
  // The samples' writer: a second write connection (WAL: the two take turns at the write lock).
  // An in-memory store is one connection's alone: its samples are committed on the loop.
  if (m.config.storage_path != ":memory:") {
    auto writer = ThreadedSampleWriter::open(m.config.storage_path, so);
    if (!writer) return fail("storage: the samples' writer connection: " + writer.error().message);
    m.samples = std::move(*writer);
    m.station->set_sample_writer(m.samples.get());
  }
  if (m.config.plant) {
    if (m.config.storage_path == ":memory:") spdlog::warn("plant: an in-memory store is not replicated");
    else m.plant = std::make_unique<PlantLink>(*m.config.plant, m.config.storage_path);
  }
  m.station->set_publisher([&m](const json& msg) { m.publish(msg); });
  // A store that cannot take the interrupted marks now (a full disk, a lock held) must not keep
  // the daemon from starting and sending the chamber to its safe setpoint: the station retries.
  auto rec = m.station->recover();
  if (!rec) spdlog::error("storage: runs left in progress not marked interrupted: {}; retried every 10 s, no run starts until then",
                          rec.error().message);
  else for (auto id : *rec) spdlog::warn("run {} was in progress when the daemon stopped: marked interrupted", id);

  // Reconnection delays in run time, not wall time (config.hpp).
  scale_backoff_to_clock(m.config.drivers, m.options.time_scale);
  if (m.config.sim_clock) m.sim_clock = std::make_unique<SimClock>(*m.config.sim_clock, std::chrono::seconds(15));
  auto chamber = drivers::open_chamber(m.config.drivers.chamber);
  if (!chamber) return fail(chamber.error().message);
  m.chamber = std::move(*chamber);
  m.thermistors = std::make_unique<drivers::ThermistorModule>(m.config.drivers.thermistors, m.config.drivers.units);
  m.wguard.emplace(m.wio.get_executor());
  m.wthread = std::thread([&m] { m.wio.run(); });
  m.tguard.emplace(m.tio.get_executor());
  m.tthread = std::thread([&m] { m.tio.run(); });
  return {};
}

int Server::run() {
  Impl& m = *impl_;
  // This thread runs the loop: a short scheduler slice, so its timer's wake-up is not left
  // waiting behind a busy task's slice (scheduling.hpp; the worker threads keep the default).
  const SliceRequest slice = request_scheduler_slice(std::chrono::microseconds(100));
  if (slice.applied) spdlog::info("acquisition loop: {}", slice.message);
  else spdlog::warn("acquisition loop: {}", slice.message);
  m.signals.async_wait([&m](boost::system::error_code ec, int sig) {
    if (!ec) m.begin_stop(sig == SIGTERM ? "SIGTERM" : "SIGINT");
  });
  m.accept_unix();
  if (m.tcp_acceptor) m.accept_tcp();
  if (m.web) m.web->start();
  if (const char* ns = std::getenv("NOTIFY_SOCKET"); ns && *ns) {
    m.notifier = std::make_unique<StatusNotifier>(m.io, *m.station, m.plans.get(),
                                                  [](std::string_view st) { return systemd::notify(st); });
    m.notifier->start();
  }

  // Start-up: the chamber goes to its safe setpoint and runs, before anything else is asked.
  const double safe = m.config.safe_setpoint_c;
  asio::post(m.wio, [&m, safe] {
    auto report = m.chamber->bring_up();
    std::string msg = report ? report->to_string() : report.error().to_string();
    auto w = m.chamber->write_setpoint_c(safe);
    auto r = m.chamber->set_running(true);
    std::string err = !w ? w.error().to_string() : (!r ? r.error().to_string() : "");
    asio::post(m.io, [&m, msg, err, safe] {
      spdlog::info("chamber bring-up:\n{}", msg);
      if (err.empty()) {
        m.written_setpoint_c = safe;
        spdlog::info("chamber at the safe setpoint {} C", safe);
      } else {
        spdlog::warn("chamber not yet at the safe setpoint: {} (retried every second)", err);
      }
    });
  });
  m.open_gyro();

  m.half_period = std::chrono::nanoseconds(static_cast<std::int64_t>(std::llround(0.5e9 / m.options.time_scale)));
  if (m.sim_clock) {
    m.paced_start();
  } else {
    m.t0 = Clock::now() + 2 * m.half_period;
    m.slot = -1;  // the first poll comes half a period before the first tick
    m.schedule();
  }

  spdlog::info("listening on {}{}; time scale {}", m.config.socket.unix_path.string(),
               m.config.socket.tcp_port ? " and " + m.config.socket.tcp_address + ":" + std::to_string(*m.config.socket.tcp_port) : "",
               m.options.time_scale);
  // One line on stdout when ready, for scripts and tests that start the daemon.
  std::cout << json{{"ready", true}, {"socket", m.config.socket.unix_path.string()},
                    {"tcp_port", m.config.socket.tcp_port ? json(*m.config.socket.tcp_port) : json(nullptr)},
                    {"pid", ::getpid()}, {"time_scale", m.options.time_scale},
                    {"web_port", m.web ? json(m.web->port()) : json(nullptr)}}
                   .dump()
            << std::endl;

  for (;;) {
    try {
      m.io.run();
      break;
    } catch (const std::exception& e) {
      // A bug escaped a handler: log it and keep serving (gpsd's "soldier on").
      spdlog::error("event loop: {}", e.what());
    }
  }
  if (m.analysis) m.analysis->stop();
  if (m.plant) m.plant->stop();
  if (m.samples) m.samples->stop();  // the station drained it when the run ended; a last guard
  m.wguard.reset();
  m.wthread.join();
  m.tguard.reset();
  m.tio.stop();
  m.tthread.join();
  remove_if_ours(m.config.socket.unix_path, m.socket_id);
  m.unix_acceptor.reset();
  return m.exit_code;
}

void Server::stop() {
  asio::post(impl_->io, [this] { impl_->begin_stop("stop requested"); });
}

void Server::post(std::function<void()> f) { asio::post(impl_->io, std::move(f)); }

}  // namespace fogbench::daemon
