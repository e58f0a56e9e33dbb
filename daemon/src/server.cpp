// The Asio server of fogbenchd: the loop, the signals, the acceptors, the live connections and
// the wiring of the parts. Everything runs on one io_context thread except the device I/O (the
// acquisition's workers, acquisition.hpp: libmodbus and the line links only have blocking
// calls), the analysis (fits, verifications, the workbench, large reads), which runs on a worker
// with its own read connection to the store and posts its replies back, and the commit of each
// second's samples, on a writer thread with a write connection of its own (sample_writer.hpp), so
// no fsync holds the loop (docs/daemon.md, "Threads"). The other writes to the store (states,
// events, models, plans) stay on the loop thread: a Store is single-threaded. Sessions take
// turns on the loop (Turns), so no number of clients can hold it.
//
// Its rooms: a session, the turns and the set of live sessions (session.hpp), the acquisition
// (acquisition.hpp: the devices, their threads and the one schedule of seconds), the analysis
// worker (analysis_worker.hpp), the sample writer (sample_writer.hpp), the loop's scheduler
// slice (scheduling.hpp), and here Server::Impl, the one object that owns the io_context, the
// signal set, the acceptors and the session set, and wires the station to the acquisition, as in
// Asio's example servers. The acceptors and the admission of a connection are apart below
// ("command socket"), from the start-up's binding (bind_sockets) to the accept loops.
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
#include <memory>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <iostream>

#include <spdlog/spdlog.h>

#include "fogbench/protocol/framing.hpp"
#include "fogbench/daemon/config_reload.hpp"
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
#include "acquisition.hpp"
#include "admission.hpp"
#include "analysis_worker.hpp"
#include "notify_status.hpp"
#include "plant_link.hpp"
#include "rate_table_link.hpp"
#include "fogbench/drivers/rate_table_registry.hpp"
#include "session.hpp"
#include "sim_clock.hpp"
#include "stop_budget.hpp"
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
// The chamber is sent to its safe setpoint on the way out; this long at most (stop_budget.hpp).
constexpr auto kShutdownDeadline = stop_budget::kSafeSetpoint;

// Whether an accept failed for want of resources, so retrying at once would spin.
bool accept_starved(const boost::system::error_code& ec) {
  const int v = ec.value();
  return ec.category() == boost::system::system_category() &&
         (v == EMFILE || v == ENFILE || v == ENOBUFS || v == ENOMEM);
}

AdmissionLimits admission_limits(const SocketConfig& s) {
  AdmissionLimits l;
  l.unix_max = static_cast<std::size_t>(s.unix_max_clients);
  l.network_max = static_cast<std::size_t>(s.max_clients);
  l.per_address_max = static_cast<std::size_t>(s.max_clients_per_address);
  return l;
}


// The mock bench's paced clock as the acquisition's PacedWorld: one simulated second per call.
class SimClockWorld final : public PacedWorld {
 public:
  explicit SimClockWorld(std::unique_ptr<SimClock> clock) : clock_(std::move(clock)) {}
  std::expected<void, std::string> step_second() override {
    auto t = clock_->advance(1);
    if (!t) return std::unexpected(t.error());
    return {};
  }

 private:
  std::unique_ptr<SimClock> clock_;
};

}  // namespace

struct Server::Impl {
  DaemonConfig config;
  ServerOptions options;
  asio::io_context io;
  asio::signal_set signals{io, SIGTERM, SIGINT};
  asio::signal_set hangup{io, SIGHUP};  // a configuration reload (systemctl reload)
  std::optional<asio::local::stream_protocol::acceptor> unix_acceptor;
  std::optional<asio::ip::tcp::acceptor> tcp_acceptor;
  SessionSet sessions;  // every transport's live connections
  // The connection limits per listener and per address (admission.hpp), and their log.
  Admission admission{admission_limits(config.socket)};
  RefusalLog refusals{std::chrono::duration_cast<Clock::duration>(
      std::chrono::duration<double>(config.socket.refusal_log_interval_s))};
  asio::steady_timer refusal_timer{io};
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
  // The devices and the schedule (acquisition.hpp); declared after the station, so its workers
  // are joined before the station goes.
  std::unique_ptr<Acquisition> acquisition;
  // The rate table (rate_table_link.hpp), when configured: commanded each second from the
  // station's answer, on a worker of its own.
  std::unique_ptr<RateTableLink> table;
  // The web panel and metrics (web.hpp), when configured.
  std::unique_ptr<web::WebServer> web;

  bool stopping = false;
  StopGuard stop_guard;  // the stop's whole budget (stop_budget.hpp)
  asio::steady_timer shutdown_timer{io};
  int exit_code = 0;

  Impl(DaemonConfig c, ServerOptions o) : config(std::move(c)), options(o) {}

  // --- command socket: admission and the accept loops (the binding is bind_sockets, below)
  template <class Socket>
  void accept_session(Socket socket, std::string peer, const std::string& address, bool may_control,
                      Admission::Ticket ticket) {
    std::string user;
    constexpr bool is_unix = std::is_same_v<Socket, asio::local::stream_protocol::socket>;
    if constexpr (is_unix) user = peer_user_name(socket.native_handle());
    auto s = std::make_shared<Session<Socket>>(std::move(socket), *handler, turns, peer, may_control,
                                               may_control ? std::string() : config.socket.tcp_token);
    s->set_peer_user(std::move(user));
    if (!is_unix) s->set_address(address);
    s->ticket = std::move(ticket);
    sessions.add(s);
    s->set_idle_timeout(config.socket.idle_timeout_s);
    if (!is_unix) s->set_first_request_timeout(config.socket.first_request_timeout_s);
    s->start();
  }

  // Connections open now, both sockets together (and the WebSockets).
  std::size_t open_sessions() { return sessions.open(); }

  // A new connection: a session, or a refusal naming its reason (admission.hpp: the listener's
  // limit or its address's). The unix socket has a share of its own, so no number of network
  // clients keeps an operator out.
  // Returns whether it was admitted.
  template <class Socket>
  bool admit(Socket socket, std::string peer, const std::string& address, Listener listener) {
    auto ticket = admission.admit(listener, address);
    if (!ticket) {
      note_refusal(listener, peer, ticket.error());
      refuse(std::move(socket), ticket.error());
      return false;
    }
    accept_session(std::move(socket), std::move(peer), address, listener == Listener::unix_socket, std::move(*ticket));
    return true;
  }

  // A refused connection, logged at most once per socket.refusal_log_interval_s with the count
  // (RefusalLog): a flood of refusals is a few lines, not one each.
  void note_refusal(Listener listener, const std::string& peer, const std::string& why) {
    if (auto line = refusals.refused(listener, peer, why, Clock::now())) {
      spdlog::warn("{}", *line);
      arm_refusal_flush();
    }
  }
  void arm_refusal_flush() {
    const auto due = refusals.flush_due();
    if (!due) return;
    refusal_timer.expires_at(*due);
    refusal_timer.async_wait([this](boost::system::error_code e) {
      if (e || stopping) return;
      if (auto line = refusals.flush(Clock::now())) {
        spdlog::warn("{}", *line);
        arm_refusal_flush();
      }
    });
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
                   accept_starved(ec) ? "retrying every 250 ms; raise LimitNOFILE or lower socket.max_clients and socket.unix_max_clients"
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
      admit(std::move(s), "unix", "", Listener::unix_socket);
      accept_unix();
    });
  }

  void accept_tcp() {
    tcp_acceptor->async_accept([this](boost::system::error_code ec, asio::ip::tcp::socket s) {
      if (stopping || ec == asio::error::operation_aborted) return;
      if (ec) return accept_failed("tcp", ec, tcp_accept_retry, &Impl::accept_tcp);
      boost::system::error_code e2;
      auto ep = s.remote_endpoint(e2);
      const std::string address = e2 ? std::string("?") : ep.address().to_string();
      const bool admitted =
          admit(std::move(s), e2 ? std::string("tcp") : address + ":" + std::to_string(ep.port()), address, Listener::tcp);
      if (admitted || !admission.network_full()) return accept_tcp();
      // Every network place taken: the next connections would be refused too (admission.hpp).
      tcp_accept_retry.expires_after(kFullNetworkPause);
      tcp_accept_retry.async_wait([this](boost::system::error_code e) {
        if (!e && !stopping) accept_tcp();
      });
    });
  }

  void publish(const json& message) {
    auto line = wire(message);
    sessions.publish(line);
    if (message.value("type", "") == "event") spdlog::info("event: {}", *line);
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
    const AcquisitionStats a = acquisition ? acquisition->stats() : AcquisitionStats{};
    in.ticks = a.ticks;
    in.ticks_skipped = a.ticks_skipped;
    in.polls_late = a.polls_late;
    in.paced_slowed = a.paced_slowed;
    in.tick_lateness_s = a.tick_late_s;
    in.tick_lateness_max_s = a.tick_late_max_s;
    return render_metrics(in);
  }

  // --- stopping
  void begin_stop(const std::string& why) {
    if (stopping) return;
    stopping = true;
    // systemd hears it before the shutdown work (the run's end, the safe setpoint) begins.
    systemd::notify("STOPPING=1\nSTATUS=stopping: " + why);
    if (notifier) notifier->stop();
    spdlog::info("stopping: {} (budget {} s: the run's end, the safe setpoint, the plant link, the workers)", why,
                 std::chrono::duration_cast<std::chrono::seconds>(stop_budget::kTotal).count());
    stop_guard.arm(stop_budget::kTotal);
    // The plant link first: its grace runs while the run ends and the chamber is made safe.
    if (plant) plant->request_stop();
    stop_guard.step("the run's end");
    station->shutdown("fogbenchd stopping: " + why);
    stop_guard.step("the safe setpoint");
    close_acceptors();
    signals.cancel();
    hangup.cancel();
    if (web) web->stop();
    sessions.close_all();
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
    // The rate table stopped beside it (its own worker): the loop ends once both are done.
    auto pending = std::make_shared<int>(table ? 2 : 1);
    auto one_done = [this, pending] {
      if (--*pending > 0) return;
      shutdown_timer.cancel();
      io.stop();
    };
    if (table)
      table->stop_table([one_done](const std::string& err) {
        if (err.empty()) spdlog::info("rate table left stopped (0 deg/s)");
        else spdlog::error("rate table not stopped: {}", err);
        one_done();
      });
    acquisition->stop([this, safe, one_done](const std::string& err) {
      if (err.empty()) spdlog::info("chamber left at the safe setpoint {} C", safe);
      else {
        spdlog::error("safe setpoint {} C not written: {}", safe, err);
        exit_code = 1;
      }
      one_done();
    });
  }

  void close_acceptors() {
    boost::system::error_code ec;
    unix_accept_retry.cancel();
    tcp_accept_retry.cancel();
    refusal_timer.cancel();
    if (unix_acceptor) unix_acceptor->close(ec);
    if (tcp_acceptor) tcp_acceptor->close(ec);
  }

  // --- the configuration's reload (config_reload.hpp, docs/daemon.md)
  void await_hangup() {
    hangup.async_wait([this](boost::system::error_code ec, int) {
      if (ec || stopping) return;
      (void)reload("SIGHUP");
      await_hangup();
    });
  }
  ApiResult<json> reload(const std::string& origin);

  // --- wiring
  std::expected<void, StartError> bind_sockets();
  std::expected<void, std::string> open_acquisition();
};

// The file read again and parsed as at start; what the table says applies is put in force in the
// station (runs started after it, max_analyses_per_address) and here (the connection limits, the
// refusal log), the rest kept as it is and named. On the loop: a file of a few kB parses in well
// under a millisecond, and the seconds of an active run are read by the acquisition meanwhile.
ApiResult<json> Server::Impl::reload(const std::string& origin) {
  const auto t0 = Clock::now();
  const auto& file = options.config_path;
  if (file.empty()) return api_error(ErrorCode::unavailable, "this daemon has no configuration file to reload");
  systemd::notify("RELOADING=1\nSTATUS=reloading " + file.string());
  auto ready = [&](const std::string& status) { systemd::notify("READY=1\nSTATUS=" + status); };
  std::ifstream in(file);
  std::stringstream text;
  if (in) text << in.rdbuf();
  if (!in) {
    const std::string why = file.string() + ": cannot be read; the configuration in force is unchanged";
    spdlog::error("configuration reload ({}): {}", origin, why);
    ready("reload failed: " + why);
    return api_error(ErrorCode::internal, why);
  }
  auto outcome = plan_reload(station->config(), text.str(), file.parent_path());
  if (!outcome) {
    const std::string why = file.string() + ": " + outcome.error() + "; the configuration in force is unchanged";
    spdlog::error("configuration reload ({}) refused: {}", origin, why);
    ready("reload refused: " + outcome.error());
    return api_error(ErrorCode::invalid_config, why);
  }
  // A plan not yet done keeps each unit in its bench position: a file that would move one is
  // refused whole, as a bad file is.
  if (plans)
    if (auto why = plans->slot_change_refusal(outcome->config.drivers.units)) {
      const std::string msg = file.string() + ": " + *why + "; the configuration in force is unchanged";
      spdlog::error("configuration reload ({}) refused: {}", origin, msg);
      ready("reload refused: " + *why);
      return api_error(ErrorCode::invalid_config, msg);
    }
  // Here: what the listeners read of the socket section, and the slots and settings for the
  // record; the drivers' own fields (scaled backoffs) stay as they are.
  const DaemonConfig& next = outcome->config;
  config.socket.max_clients = next.socket.max_clients;
  config.socket.unix_max_clients = next.socket.unix_max_clients;
  config.socket.max_clients_per_address = next.socket.max_clients_per_address;
  config.socket.max_analyses_per_address = next.socket.max_analyses_per_address;
  config.socket.refusal_log_interval_s = next.socket.refusal_log_interval_s;
  for (std::size_t i = 0; i < config.drivers.units.size() && i < next.drivers.units.size(); ++i) {
    config.drivers.units[i].serial = next.drivers.units[i].serial;
    config.drivers.units[i].slot = next.drivers.units[i].slot;
  }
  config.analysis = next.analysis;
  config.source = next.source;
  config.file_json = next.file_json;
  admission.set_limits(admission_limits(config.socket));
  refusals.set_interval(std::chrono::duration_cast<Clock::duration>(
      std::chrono::duration<double>(config.socket.refusal_log_interval_s)));
  const auto active = station->active_run_id();
  json report = outcome->report();
  station->reload_config(std::move(outcome->config));
  report["file"] = file.string();
  report["active_run"] = active ? json(*active) : json(nullptr);
  // The run acquiring meanwhile keeps what it started with; its audit trail says what the
  // reload put in force under it (a reload that applied nothing is only logged).
  if (active && !outcome->applied.empty())
    station->audit(*active, {{"cmd", "config.reload"}, {"origin", origin}, {"applied", report["applied"]},
                             {"needs_restart", report["needs_restart"]}});
  const double ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  report["elapsed_ms"] = ms;
  if (outcome->restart.empty()) spdlog::info("{} ({}, {:.1f} ms)", outcome->log_line(), origin, ms);
  else spdlog::warn("{} ({}, {:.1f} ms)", outcome->log_line(), origin, ms);
  ready("serving on " + config.socket.unix_path.string() + " (configuration reloaded)");
  return report;
}

// The command sockets: the unix socket (mode 0660, the operators' group) and, when configured,
// the TCP port. A socket another daemon answers on is never taken over; a stale one (a crash) is
// replaced. The umask is set for the bind alone, so the socket never exists with a looser mode
// (no other thread runs yet).
std::expected<void, Server::StartError> Server::Impl::bind_sockets() {
  auto fail = [](std::string message, int code = 1) { return std::unexpected(StartError{std::move(message), code}); };
  const auto& path = config.socket.unix_path;
  if (auto ok = make_dirs(path.parent_path()); !ok) return fail("socket " + path.string() + ": " + ok.error());
  if (auto ok = clear_stale_socket(path); !ok) return fail(ok.error().message, ok.error().held_by_other ? 2 : 1);
  {
    const ::mode_t old_mask = ::umask(0117);
    try {
      unix_acceptor.emplace(io, asio::local::stream_protocol::endpoint(path.string()));
    } catch (const boost::system::system_error& e) {
      ::umask(old_mask);
      return fail("socket " + path.string() + ": " + e.what());
    }
    ::umask(old_mask);
  }
  socket_id = socket_file_id(path);
  if (::chmod(path.c_str(), 0660) != 0) spdlog::warn("chmod 0660 {}: {}", path.string(), std::strerror(errno));
  if (config.socket.group) {
    const ::group* g = ::getgrnam(config.socket.group->c_str());
    if (!g) return fail("socket.group: no such group: " + *config.socket.group);
    if (::chown(path.c_str(), static_cast<uid_t>(-1), g->gr_gid) != 0)
      return fail("socket.group: chown " + path.string() + " to " + *config.socket.group + ": " +
                             std::strerror(errno));
  }
  if (config.socket.tcp_port) {
    try {
      tcp_acceptor.emplace(io, asio::ip::tcp::endpoint(asio::ip::make_address(config.socket.tcp_address),
                                                       *config.socket.tcp_port));
    } catch (const boost::system::system_error& e) {
      return fail("socket tcp " + config.socket.tcp_address + ":" + std::to_string(*config.socket.tcp_port) +
                             ": " + e.what());
    }
  }
  return {};
}

// The devices from the configuration, handed to the acquisition through their interfaces, and
// the acquisition's seconds wired to the station.
std::expected<void, std::string> Server::Impl::open_acquisition() {
  // Reconnection delays in run time, not wall time (config.hpp).
  scale_backoff_to_clock(config.drivers, options.time_scale);
  AcquisitionDevices d;
  if (config.sim_clock)
    d.paced = std::make_unique<SimClockWorld>(std::make_unique<SimClock>(*config.sim_clock, std::chrono::seconds(15)));
  auto chamber = drivers::open_chamber(config.drivers.chamber);
  if (!chamber) return std::unexpected(chamber.error().message);
  d.chamber = std::move(*chamber);
  d.thermistors = drivers::open_thermistor_source(config.drivers.thermistors, config.drivers.units);
  d.open_gyro = [this](std::optional<drivers::GyroBus>& bus) -> drivers::Result<void> {
    if (bus) return bus->reopen(config.drivers.gyro_bus);
    std::vector<drivers::GyroChannelConfig> channels;
    for (const auto& u : config.drivers.units) channels.push_back(u.gyro);
    auto b = drivers::GyroBus::open(config.drivers.gyro_bus, std::move(channels));
    if (!b) return std::unexpected(b.error());
    bus.emplace(std::move(*b));
    return {};
  };
  AcquisitionOptions o;
  o.time_scale = options.time_scale;
  o.units = config.drivers.units.size();
  o.safe_setpoint_c = config.safe_setpoint_c;
  if (config.rate_table) {
    drivers::RateTableConfig tc = *config.rate_table;
    if (options.time_scale > 1.0) {  // reconnection delays in run time, as the chamber's
      auto scale = [&](std::int64_t ms) {
        return std::max<std::int64_t>(1, std::llround(static_cast<double>(ms) / options.time_scale));
      };
      tc.line.backoff.initial_ms = scale(tc.line.backoff.initial_ms);
      tc.line.backoff.max_ms = scale(tc.line.backoff.max_ms);
    }
    auto t = drivers::open_rate_table(tc);
    if (!t) return std::unexpected(t.error().message);
    table = std::make_unique<RateTableLink>(io, std::move(*t), config.rate_table_status_tolerance);
    spdlog::info("rate table {} {} ({})", tc.name, tc.kind, tc.line.describe());
  }
  TickSink sink;
  sink.on_tick = [this](std::int64_t k, const TickInput& in) {
    if (!table) return station->tick(static_cast<double>(k), in).setpoint_c;
    // The table's state as its worker last saw it joins the second; the station's rate goes
    // back to the table (0 deg/s with no run, and from the second a run ends).
    TickInput with_table = in;
    with_table.rate_table = table->reading();
    const TickOutput out = station->tick(static_cast<double>(k), with_table);
    if (!stopping) table->command(out.rate_dps);
    return out.setpoint_c;
  };
  sink.run_active = [this] { return station->active_run_id().has_value(); };
  acquisition = std::make_unique<Acquisition>(io, o, std::move(d), std::move(sink));
  return {};
}

Server::Server(DaemonConfig config, ServerOptions options)
    : impl_(std::make_unique<Impl>(std::move(config), options)) {}

Server::~Server() {
  if (impl_ && impl_->analysis) impl_->analysis->stop(stop_budget::kAnalysis);
  if (impl_ && impl_->samples) impl_->samples->stop(stop_budget::kSampleWriter);
  if (impl_) impl_->acquisition.reset();  // stops and joins the device workers
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

  // The command sockets: bound before the store is opened, so a second daemon on the same
  // socket changes nothing.
  if (auto ok = m.bind_sockets(); !ok) return std::unexpected(ok.error());

  storage::OpenOptions so;
  so.synchronous_full = m.config.storage_synchronous_full;
  so.size_limit_bytes = m.config.storage_size_limit_bytes;
  so.file_mode = kStoreFileMode;
  auto store = storage::Store::open(m.config.storage_path, so);
  if (!store) return fail("storage: " + store.error().message);
  m.store.emplace(std::move(*store));
  // Which schema the store is at, for an upgrade's or a downgrade's record (docs/storage.md).
  spdlog::info("store {} at schema version {}", m.config.storage_path.string(), m.store->schema_version());
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
  if (!m.options.config_path.empty()) m.station->set_reloader([&m] { return m.reload("config.reload"); });
  if (m.config.web) {
    web::WebServer::Hooks hooks;
    hooks.take = [&m](const std::string& address, const std::string& peer) {
      auto t = m.admission.admit(Listener::web, address);
      if (!t) m.note_refusal(Listener::web, peer, t.error());
      return t;
    };
    hooks.full = [&m] { return m.admission.network_full(); };
    hooks.first_request_timeout_s = m.config.socket.first_request_timeout_s;
    hooks.admit = [&m](const std::shared_ptr<SessionBase>& s) { m.sessions.add(s); };
    hooks.metrics = [&m] { return m.metrics(); };
    const std::string& token = m.config.web->token.empty() ? m.config.socket.tcp_token : m.config.web->token;
    m.web = std::make_unique<web::WebServer>(m.io, *m.handler, *m.config.web, token, std::move(hooks));
    if (auto ok = m.web->bind(); !ok) return fail(ok.error());
  }
  m.plans = std::make_unique<PlanRunner>(*m.station, m.station->store());
  m.station->set_plan_runner(m.plans.get());  // where the handler finds it
  m.station->add_tick_listener(m.plans.get());  // the runner listens to the ticks
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
    else {
      m.plant = std::make_unique<PlantLink>(*m.config.plant, m.config.storage_path);
      m.station->set_plant_link_state([link = m.plant.get()] {
        const PlantLinkState st = link->state();
        return json{{"link", st.state},
                    {"stalled", st.stalled},
                    {"sending_run_id", st.run_id ? json(st.run_id) : json(nullptr)},
                    {"link_busy_s", st.busy_s},
                    {"link_quiet_s", st.quiet_s}};
      });
    }
  }
  m.station->set_publisher([&m](const json& msg) { m.publish(msg); });
  // A store that cannot take the interrupted marks now (a full disk, a lock held) must not keep
  // the daemon from starting and sending the chamber to its safe setpoint: the station retries.
  auto rec = m.station->recover();
  if (!rec) spdlog::error("storage: runs left in progress not marked interrupted: {}; retried every 10 s, no run starts until then",
                          rec.error().message);
  else for (auto id : *rec) spdlog::warn("run {} was in progress when the daemon stopped: marked interrupted", id);

  if (auto ok = m.open_acquisition(); !ok) return fail(ok.error());
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
  m.await_hangup();
  m.accept_unix();
  if (m.tcp_acceptor) m.accept_tcp();
  if (m.web) m.web->start();
  if (const char* ns = std::getenv("NOTIFY_SOCKET"); ns && *ns) {
    m.notifier = std::make_unique<StatusNotifier>(m.io, *m.station, m.plans.get(),
                                                  [](std::string_view st) { return systemd::notify(st); });
    m.notifier->start();
  }

  // The chamber's bring-up to its safe setpoint, the gyro bus and the schedule of seconds.
  m.acquisition->start();

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
  // The threads, each within its share of the stop's budget (stop_budget.hpp); one that would not
  // end is left to the process's end, which comes at once (below) rather than after a join that
  // could hang past systemd's TimeoutStopSec.
  using namespace stop_budget;
  const auto now = std::chrono::steady_clock::now();
  m.stop_guard.arm(kTotal);  // a loop that ended without begin_stop (a test's io.stop)
  bool all_ended = true;
  if (m.analysis) {
    m.stop_guard.step("the analysis worker");
    all_ended &= m.analysis->stop(kAnalysis);
  }
  if (m.plant) {
    m.stop_guard.step("the plant link");
    const auto from = m.stopping ? m.stop_guard.began() : now;
    all_ended &= m.plant->stop(std::max(from + kPlantGrace, std::chrono::steady_clock::now()),
                               std::max(from + kPlantGrace + kPlantAfterAbandon, std::chrono::steady_clock::now()));
  }
  if (m.samples) {
    m.stop_guard.step("the sample writer");
    m.samples->stop(kSampleWriter);  // the station drained it when the run ended; a last guard
  }
  m.stop_guard.step("the device workers");
  m.acquisition->join();
  m.stop_guard.step("done");
  remove_if_ours(m.config.socket.unix_path, m.socket_id);
  m.unix_acceptor.reset();
  spdlog::info("stopped in {:.2f} s (budget {} s), exit status {}", m.stop_guard.elapsed_s(),
               std::chrono::duration_cast<std::chrono::seconds>(kTotal).count(), m.exit_code);
  m.stop_guard.disarm();
  if (!all_ended) {
    // A thread still in a call that no deadline reaches: the process ends here, without the
    // destructors that would join it. The store's commits are on disk (SQLite's WAL).
    spdlog::warn("stopping: a thread did not end (see above): the process exits without waiting for it");
    spdlog::default_logger()->flush();
    std::_Exit(m.exit_code);
  }
  return m.exit_code;
}

void Server::stop() {
  asio::post(impl_->io, [this] { impl_->begin_stop("stop requested"); });
}

void Server::post(std::function<void()> f) { asio::post(impl_->io, std::move(f)); }

}  // namespace fogbench::daemon
