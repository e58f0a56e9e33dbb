// The mock bench's server loop and clock; see bench.hpp.
#include "bench.hpp"

#include <arpa/inet.h>
#include <modbus/modbus.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <signal.h>
#include <spdlog/spdlog.h>
#include <sys/eventfd.h>
#include <sys/signalfd.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstring>
#include <mutex>
#include <optional>
#include <random>
#include <span>
#include <thread>

#include "control.hpp"
#include "faults.hpp"
#include "fogbench/drivers/can_frame.hpp"
#include "frames.hpp"
#include "registers.hpp"

namespace fogbench::mock {

using nlohmann::json;
using SteadyClock = std::chrono::steady_clock;

namespace {

// Below this the clock does not sleep: frames due within it go out in one batch, so a high
// frame rate times a high time scale costs one wake-up per millisecond, not one per frame.
constexpr auto min_sleep = std::chrono::milliseconds(1);
// Air within this of the setpoint shows the status bit at_setpoint, degC.
constexpr double at_setpoint_band_c = 0.5;
// The physics accepts setpoints in this range; a client's wilder value is clamped, degC.
constexpr double min_setpoint_c = -100.0, max_setpoint_c = 250.0;
// Requested socket send buffer of a CAN client: about 25,000 frames (the kernel charges each
// 16-byte datagram some 300 bytes), so a reader that pauses for a scheduler hiccup of a second
// at 20,000 frames/s loses nothing.
constexpr int can_sndbuf_bytes = 8 << 20;

std::string errno_text(int err) { return std::strerror(err); }

// Makes `path` free for a listening unix socket: a stale socket nobody listens on is removed;
// a live one or any other file is an error.
std::expected<void, std::string> free_unix_path(const std::string& path, int type) {
  struct stat st {};
  if (::lstat(path.c_str(), &st) != 0) return {};
  if (!S_ISSOCK(st.st_mode)) return std::unexpected(path + ": exists and is not a socket");
  const int probe = ::socket(AF_UNIX, type | SOCK_CLOEXEC, 0);
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  std::memcpy(addr.sun_path, path.c_str(), path.size() + 1);
  const bool live = ::connect(probe, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0;
  ::close(probe);
  if (live) return std::unexpected(path + ": another process is listening there");
  ::unlink(path.c_str());
  return {};
}

std::expected<int, std::string> listen_unix(const std::string& path, int type) {
  sockaddr_un addr{};
  if (path.empty() || path.size() >= sizeof addr.sun_path) {
    return std::unexpected(path + ": a unix socket path must be 1.." + std::to_string(sizeof addr.sun_path - 1) + " characters");
  }
  if (auto ok = free_unix_path(path, type); !ok) return std::unexpected(ok.error());
  addr.sun_family = AF_UNIX;
  std::memcpy(addr.sun_path, path.c_str(), path.size() + 1);
  const int fd = ::socket(AF_UNIX, type | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
  if (fd < 0) return std::unexpected(path + ": socket: " + errno_text(errno));
  if (::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0 || ::listen(fd, 16) != 0) {
    const int err = errno;
    ::close(fd);
    return std::unexpected(path + ": " + errno_text(err));
  }
  return fd;
}

}  // namespace

struct Bench::Impl final : ControlHandler {
  // ---- configuration ----
  BenchConfig cfg;
  std::vector<std::string> serials;
  std::vector<double> counts_per_dph;

  // ---- shared between the threads, under `mutex` ----
  struct UnitStatus {
    double t1_c = 0, t2_c = 0, true_t1_c = 0, true_t2_c = 0, gyro_dph = 0;
    std::uint64_t frames_sent = 0, frames_lost = 0, frames_corrupted = 0;
    bool powered = true;
    double powered_on_at_s = 0;  // simulated time of the gyro's last power-on
  };
  struct Snapshot {
    double time_s = 0, setpoint_c = 0, air_c = 0, pv_c = 0;
    bool running = true;
    std::vector<UnitStatus> units;
  };
  std::mutex mutex;
  std::optional<ChamberRegisters> chamber;
  std::optional<ThermistorRegisters> thermistors;
  FaultState faults;
  Snapshot snap;

  // ---- CAN clients: accepted by the server loop, written by the clock, under `can_mutex` ----
  std::mutex can_mutex;
  std::vector<int> can_clients;
  std::uint64_t can_dropped = 0;  // frames a slow client's full socket could not take

  // ---- clock thread ----
  std::optional<sim::World> world;
  std::vector<GyroStream> streams;  // each unit's gyro at its frame rate
  std::thread clock_thread;
  std::mutex cv_mutex;
  std::condition_variable cv;
  std::atomic<bool> stopping{false};
  // --paced: the clock steps up to paced_target (seconds asked for by advance()) and reports
  // paced_done once every frame of them is sent; both under cv_mutex.
  std::condition_variable done_cv;
  std::int64_t paced_target = 0, paced_done = 0;

  // ---- server loop (the thread that calls run()) ----
  struct Listener {
    int port = 0;
    int fd = -1;
    std::vector<Device> devices;  // what it serves: the first answers unit id 255 too
  };
  struct ModbusClient {
    int fd = -1;
    std::size_t listener = 0;
    bool pending = false;                  // a stalled reply waits: read no further request
    std::vector<std::uint8_t> query;
    int query_length = 0;
    Device device = Device::chamber;
    SteadyClock::time_point due{};
  };
  struct ControlClient {
    int fd = -1;
    LineBuffer in;
    std::string out;
  };
  std::vector<Listener> listeners;
  std::vector<ModbusClient> modbus_clients;
  std::vector<ControlClient> control_clients;
  modbus_t* serve_ctx = nullptr;  // receives and replies on whichever client socket is set
  int can_fd = -1, control_fd = -1, signal_fd = -1, wake_fd = -1;
  std::atomic<bool> stop_requested{false};
  sigset_t blocked{};

  ~Impl() override {
    stop_clock();
    close_all();
    if (serve_ctx != nullptr) modbus_free(serve_ctx);
  }

  // ===== set-up ===============================================================================

  std::expected<void, std::string> init() {
    for (const auto& u : cfg.units) {
      serials.push_back(u.serial);
      counts_per_dph.push_back(u.counts_per_dph());
    }
    if (cfg.sim.units.size() != cfg.units.size()) return std::unexpected(std::string("physics and layout disagree on the number of units"));
    if (!(cfg.time_scale > 0) || cfg.time_scale > 100000) return std::unexpected(std::string("--time-scale must be in (0, 100000]"));
    auto w = sim::World::create(cfg.sim);
    if (!w) return std::unexpected(w.error());
    world.emplace(std::move(*w));
    for (std::size_t u = 0; u < cfg.units.size(); ++u) {
      const auto& g = cfg.sim.units[u].gyro;
      const Warmup wu = u < cfg.warmup.size() ? cfg.warmup[u] : Warmup{};
      if (!(wu.tau_s > 0)) return std::unexpected("unit " + cfg.units[u].serial + ": warm-up tau_s must be positive");
      streams.emplace_back(StreamParams{.frame_rate_hz = cfg.units[u].frame_rate_hz,
                                        .counts_per_dph = counts_per_dph[u],
                                        .ar = g.ar,
                                        .sigma_a_dph = g.sigma_a_dph,
                                        .outlier_rate_per_s = g.outlier_rate_per_s,
                                        .outlier_dph = g.outlier_dph,
                                        .white_dph = cfg.frame_noise_dph,
                                        .warmup_dph = wu.dph,
                                        .warmup_tau_s = wu.tau_s});
    }

    auto ch = ChamberRegisters::create(cfg.map.map, cfg.sim.start_c, true);
    if (!ch) return std::unexpected("chamber map: " + ch.error());
    chamber.emplace(std::move(*ch));
    auto th = ThermistorRegisters::create(cfg.units);
    if (!th) return std::unexpected("thermistor module: " + th.error());
    thermistors.emplace(std::move(*th));
    faults.units.assign(cfg.units.size(), {});
    snap.time_s = 0;
    snap.setpoint_c = snap.air_c = snap.pv_c = cfg.sim.start_c;
    snap.units.assign(cfg.units.size(), {});
    for (std::size_t u = 0; u < cfg.units.size(); ++u) {
      for (int s : {1, 2}) thermistors->show(u, s, cfg.sim.start_c, false);
      snap.units[u].t1_c = snap.units[u].t2_c = snap.units[u].true_t1_c = snap.units[u].true_t2_c = cfg.sim.start_c;
    }

    // Signals arrive on a descriptor the loop polls; blocked before any thread exists, so the
    // clock thread inherits the mask.
    sigemptyset(&blocked);
    sigaddset(&blocked, SIGINT);
    sigaddset(&blocked, SIGTERM);
    pthread_sigmask(SIG_BLOCK, &blocked, nullptr);
    ::signal(SIGPIPE, SIG_IGN);
    signal_fd = ::signalfd(-1, &blocked, SFD_CLOEXEC | SFD_NONBLOCK);
    wake_fd = ::eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK);
    if (signal_fd < 0 || wake_fd < 0) return std::unexpected("signalfd/eventfd: " + errno_text(errno));

    serve_ctx = modbus_new_tcp("127.0.0.1", 0);
    if (serve_ctx == nullptr) return std::unexpected("libmodbus: " + std::string(modbus_strerror(errno)));
    // A request split across packets may wait this long for its rest; the response timeout is
    // only libmodbus's pause before flushing a malformed request. Both bound the loop's stalls.
    modbus_set_byte_timeout(serve_ctx, 0, 100000);
    modbus_set_response_timeout(serve_ctx, 0, 10000);

    listeners.push_back({cfg.where.chamber_port, -1, {Device::chamber}});
    if (cfg.gateway) {
      listeners[0].devices.push_back(Device::thermistors);
    } else {
      listeners.push_back({cfg.where.thermistor_port, -1, {Device::thermistors}});
    }
    for (auto& l : listeners) {
      if (auto ok = open_listener(l); !ok) return ok;
    }
    cfg.where.chamber_port = listeners[0].port;
    cfg.where.thermistor_port = cfg.gateway ? listeners[0].port : listeners[1].port;

    auto can = listen_unix(cfg.where.can_socket, SOCK_SEQPACKET);
    if (!can) return std::unexpected("CAN socket " + can.error());
    can_fd = *can;
    if (!cfg.control_path.empty()) {
      auto ctl = listen_unix(cfg.control_path, SOCK_STREAM);
      if (!ctl) return std::unexpected("control socket " + ctl.error());
      control_fd = *ctl;
    }
    for (const auto& f : cfg.start_faults) {
      if (auto ok = fault(f); !ok) return std::unexpected("--fault " + f.value("name", std::string("?")) + ": " + ok.error());
    }
    return {};
  }

  std::expected<void, std::string> open_listener(Listener& l) {
    modbus_t* ctx = modbus_new_tcp(cfg.where.host.c_str(), l.port);
    if (ctx == nullptr) return std::unexpected("Modbus listener " + cfg.where.host + ": " + modbus_strerror(errno));
    const int fd = modbus_tcp_listen(ctx, 16);
    const int err = errno;
    modbus_free(ctx);  // only the socket is kept: it is all the listener is
    if (fd < 0) {
      return std::unexpected("Modbus listener " + cfg.where.host + ":" + std::to_string(l.port) + ": " + modbus_strerror(err));
    }
    if (l.port == 0) {
      sockaddr_in addr{};
      socklen_t len = sizeof addr;
      ::getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len);
      l.port = ntohs(addr.sin_port);  // kept, so a refused listener reopens on the same port
    }
    l.fd = fd;
    return {};
  }

  void close_all() {
    for (auto& l : listeners) {
      if (l.fd >= 0) ::close(l.fd);
      l.fd = -1;
    }
    for (auto& c : modbus_clients) {
      if (c.fd >= 0) ::close(c.fd);
    }
    modbus_clients.clear();
    for (auto& c : control_clients) {
      if (c.fd >= 0) ::close(c.fd);
    }
    control_clients.clear();
    {
      std::lock_guard lock(can_mutex);
      for (int fd : can_clients) ::close(fd);
      can_clients.clear();
    }
    if (can_fd >= 0) {
      ::close(can_fd);
      ::unlink(cfg.where.can_socket.c_str());
      can_fd = -1;
    }
    if (control_fd >= 0) {
      ::close(control_fd);
      ::unlink(cfg.control_path.c_str());
      control_fd = -1;
    }
    for (int* fd : {&signal_fd, &wake_fd}) {
      if (*fd >= 0) ::close(*fd);
      *fd = -1;
    }
  }

  // ===== control handler (called on the server loop) ==========================================

  std::expected<void, std::string> fault(const json& command) override {
    auto cmd = parse_fault_command(command, serials);
    if (!cmd) return std::unexpected(cmd.error());
    {
      std::lock_guard lock(mutex);
      apply_fault(faults, *cmd, snap.time_s);
      // Register-level faults show at once, so a client reading right after the reply sees them.
      chamber->show_alarm(faults.alarm);
      for (std::size_t u = 0; u < faults.units.size(); ++u) {
        thermistors->show(u, 1, snap.units[u].t1_c, faults.units[u].open_t1);
        thermistors->show(u, 2, snap.units[u].t2_c, faults.units[u].open_t2);
      }
    }
    if (cmd->kind == FaultKind::refuse_modbus) update_listeners();
    if (cmd->kind == FaultKind::drop_modbus && cmd->on) drop_clients(cmd->device);
    spdlog::info("fault {} {}: {}", to_string(cmd->kind), cmd->on ? "on" : "off", command.dump());
    return {};
  }

  json status() override {
    json out;
    {
      std::lock_guard lock(mutex);
      out = {{"time_s", snap.time_s},      {"time_scale", cfg.time_scale}, {"setpoint_c", snap.setpoint_c},
             {"running", snap.running},    {"air_c", snap.air_c},          {"pv_c", snap.pv_c}};
      json units = json::array();
      for (std::size_t i = 0; i < snap.units.size(); ++i) {
        const auto& u = snap.units[i];
        units.push_back({{"unit", i}, {"serial", serials[i]}, {"node_id", cfg.units[i].gyro.node_id},
                         {"t1_c", u.t1_c}, {"t2_c", u.t2_c}, {"true_t1_c", u.true_t1_c}, {"true_t2_c", u.true_t2_c},
                         {"gyro_dph", u.powered ? json(u.gyro_dph) : json(nullptr)}, {"frames_sent", u.frames_sent},
                         {"powered", u.powered}, {"powered_on_at_s", u.powered_on_at_s},
                         {"frames_lost", u.frames_lost}, {"frames_corrupted", u.frames_corrupted}});
      }
      out["units"] = std::move(units);
      out["faults"] = active_faults(faults, serials, snap.time_s);
    }
    std::size_t modbus_open = 0;
    for (const auto& c : modbus_clients) modbus_open += c.fd >= 0 ? 1 : 0;
    out["modbus_clients"] = modbus_open;
    std::lock_guard lock(can_mutex);
    out["can_clients"] = can_clients.size();
    out["can_frames_dropped"] = can_dropped;
    return out;
  }

  void stop() override { request_stop("stop command"); }

  // Called on the server loop: the clock thread steps, and the reply waits for it, so a client
  // that reads its reply finds every frame of those seconds already in its CAN socket and the
  // registers showing their end. Modbus requests wait meanwhile (microseconds per second).
  std::expected<double, std::string> advance(std::int64_t seconds) override {
    if (!cfg.paced) return std::unexpected(std::string("the bench keeps its own clock (start it with --paced)"));
    std::unique_lock lock(cv_mutex);
    paced_target = paced_done + seconds;
    const std::int64_t want = paced_target;
    cv.notify_all();
    if (!done_cv.wait_for(lock, std::chrono::seconds(10), [&] { return paced_done >= want || stopping.load(); }))
      return std::unexpected("the clock did not reach " + std::to_string(want) + " s within 10 s");
    if (paced_done < want) return std::unexpected(std::string("stopping"));
    return static_cast<double>(paced_done);
  }

  void request_stop(const char* why) {
    if (!stop_requested.exchange(true)) spdlog::info("stopping: {}", why);
    const std::uint64_t one = 1;
    [[maybe_unused]] auto n = ::write(wake_fd, &one, sizeof one);
  }

  // ===== Modbus ===============================================================================

  bool refused(const Listener& l) const {
    return std::ranges::any_of(l.devices, [&](Device d) { return faults.refuse[static_cast<std::size_t>(d)]; });
  }

  void update_listeners() {
    for (auto& l : listeners) {
      bool refuse = false;
      {
        std::lock_guard lock(mutex);
        refuse = refused(l);
      }
      if (refuse && l.fd >= 0) {
        ::close(l.fd);  // connects now get ECONNREFUSED; clients already connected stay
        l.fd = -1;
      } else if (!refuse && l.fd < 0) {
        if (auto ok = open_listener(l); !ok) spdlog::error("reopening a refused listener: {}", ok.error());
      }
    }
  }

  void drop_clients(std::optional<Device> device) {
    std::size_t n = 0;
    for (auto& c : modbus_clients) {
      const auto& served = listeners[c.listener].devices;
      if (c.fd >= 0 && (!device || std::ranges::find(served, *device) != served.end())) {
        ::close(c.fd);
        c.fd = -1;
        ++n;
      }
    }
    spdlog::info("dropped {} Modbus connection(s)", n);
  }

  void accept_modbus(std::size_t li) {
    // Non-blocking: modbus_reply() sends while the register mutex is held, and a client that
    // never reads its replies must cost its connection (EAGAIN closes it), not the clock.
    // libmodbus waits in select() before each recv, so receiving is unaffected.
    const int fd = ::accept4(listeners[li].fd, nullptr, nullptr, SOCK_CLOEXEC | SOCK_NONBLOCK);
    if (fd < 0) {
      if (errno != EAGAIN && errno != EINTR) spdlog::warn("Modbus accept: {}", errno_text(errno));
      return;
    }
    const int one = 1;
    ::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
    ModbusClient c;
    c.fd = fd;
    c.listener = li;
    modbus_clients.push_back(std::move(c));
    spdlog::debug("Modbus client connected on port {}", listeners[li].port);
  }

  std::optional<Device> device_for_unit(const Listener& l, int unit_id) const {
    if (unit_id == 255) return l.devices.front();  // "the device itself" on Modbus TCP
    for (Device d : l.devices) {
      const int id = d == Device::chamber ? cfg.where.chamber_unit : cfg.where.thermistor_unit;
      if (id == unit_id) return d;
    }
    return std::nullopt;
  }

  void close_client(ModbusClient& c, const char* why) {
    spdlog::debug("Modbus client on port {} closed: {}", listeners[c.listener].port, why);
    ::close(c.fd);
    c.fd = -1;
  }

  void read_request(ModbusClient& c) {
    std::uint8_t query[MODBUS_TCP_MAX_ADU_LENGTH];
    modbus_set_socket(serve_ctx, c.fd);
    const int rc = modbus_receive(serve_ctx, query);
    if (rc < 0) {
      close_client(c, modbus_strerror(errno));
      return;
    }
    if (rc == 0) return;
    const int unit_id = query[modbus_get_header_length(serve_ctx) - 1];
    const auto device = device_for_unit(listeners[c.listener], unit_id);
    if (!device) {
      // A gateway's answer for a unit it does not have: the client sees a protocol error.
      modbus_reply_exception(serve_ctx, query, MODBUS_EXCEPTION_GATEWAY_TARGET);
      return;
    }
    int stall_ms = 0;
    {
      std::lock_guard lock(mutex);
      stall_ms = faults.stall_ms[static_cast<std::size_t>(*device)];
    }
    if (stall_ms > 0) {
      c.pending = true;
      c.query.assign(query, query + rc);
      c.query_length = rc;
      c.device = *device;
      c.due = SteadyClock::now() + std::chrono::milliseconds(stall_ms);
      return;
    }
    reply(c, query, rc, *device);
  }

  void reply(ModbusClient& c, const std::uint8_t* query, int length, Device device) {
    modbus_set_socket(serve_ctx, c.fd);
    int rc = 0;
    {
      std::lock_guard lock(mutex);
      modbus_mapping_t* m = device == Device::chamber ? chamber->mapping() : thermistors->mapping();
      rc = modbus_reply(serve_ctx, query, length, m);
    }
    if (rc < 0) close_client(c, modbus_strerror(errno));
  }

  void serve_due_replies(SteadyClock::time_point now) {
    for (auto& c : modbus_clients) {
      if (c.fd >= 0 && c.pending && c.due <= now) {
        c.pending = false;
        reply(c, c.query.data(), c.query_length, c.device);
      }
    }
  }

  // ===== control socket =======================================================================

  void accept_control() {
    const int fd = ::accept4(control_fd, nullptr, nullptr, SOCK_CLOEXEC | SOCK_NONBLOCK);
    if (fd < 0) return;
    ControlClient c;
    c.fd = fd;
    control_clients.push_back(std::move(c));
  }

  void flush_control(ControlClient& c) {
    while (!c.out.empty()) {
      const auto n = ::send(c.fd, c.out.data(), c.out.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
      if (n < 0) {
        if (errno == EAGAIN || errno == EINTR) return;
        ::close(c.fd);
        c.fd = -1;
        return;
      }
      c.out.erase(0, static_cast<std::size_t>(n));
    }
  }

  void read_control(ControlClient& c) {
    char buf[4096];
    const auto n = ::recv(c.fd, buf, sizeof buf, 0);
    if (n == 0 || (n < 0 && errno != EAGAIN && errno != EINTR)) {
      ::close(c.fd);
      c.fd = -1;
      return;
    }
    if (n < 0) return;
    c.in.append(std::string_view(buf, static_cast<std::size_t>(n)));
    while (auto line = c.in.next_line()) {
      if (line->empty()) continue;
      c.out += handle_line(*line, *this) + "\n";
    }
    if (c.in.overflowed()) {
      c.out += json{{"ok", false}, {"error", "request longer than " + std::to_string(max_control_line) + " bytes"}}.dump() + "\n";
      flush_control(c);
      if (c.fd >= 0) ::close(c.fd);
      c.fd = -1;
      return;
    }
    flush_control(c);
  }

  // ===== CAN ==================================================================================

  void accept_can() {
    const int fd = ::accept4(can_fd, nullptr, nullptr, SOCK_CLOEXEC);
    if (fd < 0) return;
    // Root may pass the system's cap (SO_SNDBUFFORCE); others get what wmem_max allows.
    if (::setsockopt(fd, SOL_SOCKET, SO_SNDBUFFORCE, &can_sndbuf_bytes, sizeof can_sndbuf_bytes) != 0) {
      ::setsockopt(fd, SOL_SOCKET, SO_SNDBUF, &can_sndbuf_bytes, sizeof can_sndbuf_bytes);
    }
    std::lock_guard lock(can_mutex);
    can_clients.push_back(fd);
    spdlog::info("CAN client connected ({} now)", can_clients.size());
  }

  // Sends the frames to every CAN client without blocking; a client whose socket is full misses
  // the rest (its reader sees the gap in the sequence counter), one that left is closed.
  void send_frames(std::span<const ::can_frame> frames) {
    if (frames.empty()) return;
    std::lock_guard lock(can_mutex);
    for (auto it = can_clients.begin(); it != can_clients.end();) {
      std::size_t done = 0;
      bool gone = false;
      while (done < frames.size()) {
        constexpr std::size_t batch = 64;
        mmsghdr msgs[batch]{};
        iovec iov[batch]{};
        const std::size_t n = std::min(batch, frames.size() - done);
        for (std::size_t i = 0; i < n; ++i) {
          iov[i].iov_base = const_cast<::can_frame*>(&frames[done + i]);
          iov[i].iov_len = sizeof(::can_frame);
          msgs[i].msg_hdr.msg_iov = &iov[i];
          msgs[i].msg_hdr.msg_iovlen = 1;
        }
        const int r = ::sendmmsg(*it, msgs, static_cast<unsigned>(n), MSG_DONTWAIT | MSG_NOSIGNAL);
        if (r < 0) {
          if (errno == EINTR) continue;
          if (errno != EAGAIN && errno != EWOULDBLOCK && errno != ENOBUFS) gone = true;
          break;
        }
        done += static_cast<std::size_t>(r);
      }
      if (gone) {
        ::close(*it);
        it = can_clients.erase(it);
        spdlog::info("CAN client left ({} now)", can_clients.size());
        continue;
      }
      if (done < frames.size()) {
        can_dropped += frames.size() - done;
        warn_slow_client(frames.size() - done);
      }
      ++it;
    }
  }

  SteadyClock::time_point last_slow_warning{};
  void warn_slow_client(std::size_t n) {
    const auto now = SteadyClock::now();
    if (now - last_slow_warning < std::chrono::seconds(1)) return;
    last_slow_warning = now;
    spdlog::warn("a CAN client is not reading fast enough: {} frame(s) dropped ({} in all)", n, can_dropped);
  }

  // ===== clock thread =========================================================================

  struct Batch {  // the frame slots of the current simulated second, per unit
    std::vector<std::vector<StreamFrame>> frames;
    std::vector<std::size_t> next;   // next slot to send
    std::int64_t second = -1;        // its start, simulated seconds
  };

  void clock_loop() {
    const auto t0 = SteadyClock::now();
    const double k = cfg.time_scale;
    auto wall = [&](double sim_s) {
      return t0 + std::chrono::duration_cast<SteadyClock::duration>(std::chrono::duration<double>(sim_s / k));
    };
    const std::size_t nu = cfg.units.size();
    Batch b;
    b.frames.resize(nu);
    b.next.assign(nu, 0);
    std::mt19937_64 rng(cfg.sim.seed ^ 0x9E3779B97F4A7C15ull);  // its own stream: the world's is untouched
    std::vector<::can_frame> out;
    std::int64_t next_step = 0;
    double last_setpoint_c = cfg.sim.start_c;
    auto last_behind_warning = SteadyClock::time_point{};
    auto due = [&](std::size_t u, std::size_t j) {
      return wall(static_cast<double>(b.second) + static_cast<double>(j) / cfg.units[u].frame_rate_hz);
    };

    while (!stopping) {
      auto now = SteadyClock::now();
      auto step_due = [&] {
        if (!cfg.paced) return wall(static_cast<double>(next_step)) <= now;
        std::lock_guard lock(cv_mutex);
        return next_step < paced_target;
      };
      while (step_due() && !stopping) {
        emit(b, SteadyClock::time_point::max(), due, rng, out);  // the rest of the second, now due
        step(b, next_step, last_setpoint_c, rng);
        ++next_step;
        if (cfg.duration_s > 0 && static_cast<double>(next_step) >= cfg.duration_s) {
          emit(b, SteadyClock::time_point::max(), due, rng, out);
          request_stop("duration reached");
          stopping = true;
          break;
        }
        if (!cfg.paced && now - wall(static_cast<double>(next_step)) > std::chrono::seconds(1) &&
            now - last_behind_warning > std::chrono::seconds(5)) {
          last_behind_warning = now;
          spdlog::warn("the physics runs {:.1f} s (wall) behind the scaled clock: lower --time-scale",
                       std::chrono::duration<double>(now - wall(static_cast<double>(next_step))).count());
        }
      }
      if (stopping) break;
      if (cfg.paced) {
        // Every frame of the seconds stepped goes out before the client hears they are done;
        // then nothing moves until it asks for more.
        emit(b, SteadyClock::time_point::max(), due, rng, out);
        std::unique_lock lock(cv_mutex);
        paced_done = next_step;
        done_cv.notify_all();
        // Bounded: `stopping` is set without cv_mutex, so a wake-up could slip past the wait.
        cv.wait_for(lock, std::chrono::milliseconds(100), [&] { return stopping.load() || paced_target > next_step; });
        continue;
      }
      emit(b, now, due, rng, out);
      auto wake = wall(static_cast<double>(next_step));
      for (std::size_t u = 0; u < nu; ++u) {
        if (b.next[u] < b.frames[u].size()) wake = std::min(wake, due(u, b.next[u]));
      }
      wake = std::max(wake, now + min_sleep);
      std::unique_lock lock(cv_mutex);
      cv.wait_until(lock, wake, [&] { return stopping.load(); });
    }
  }

  // Advances the world one second and shows its state in the registers.
  void step(Batch& b, std::int64_t second, double& last_setpoint_c, std::mt19937_64& rng) {
    double setpoint_c = last_setpoint_c;
    bool running = true;
    std::vector<UnitFaults> unit_faults;
    {
      std::lock_guard lock(mutex);
      setpoint_c = chamber->setpoint_c(last_setpoint_c);
      running = chamber->running();
      unit_faults = faults.units;
    }
    if (setpoint_c != last_setpoint_c) spdlog::debug("setpoint {} degC", setpoint_c);
    last_setpoint_c = setpoint_c;
    const double commanded = std::clamp(setpoint_c, min_setpoint_c, max_setpoint_c);
    // A stopped chamber no longer controls: its air drifts back to the room's temperature.
    world->step(running ? commanded : cfg.sim.start_c);
    const double pv_c = world->chamber_reading_c();
    b.second = second;
    std::vector<double> gyro_dph(cfg.units.size());
    for (std::size_t u = 0; u < cfg.units.size(); ++u) {
      const auto& f = unit_faults[u];
      const double spike = static_cast<double>(second) < f.spike_until_s ? f.spike_dph : 0.0;
      // The world's deterministic drift for the second; the gyro's noise is made at the frame
      // rate by its stream (the world's own 1 s noise is left out), so the reader's 1 s means
      // carry the specified AR noise whatever their phase.
      const auto s = world->sample(u);
      streams[u].second(second, s.gyro_dph - s.noise_dph + spike, {f.power_off_from_s, f.power_on_at_s}, rng, b.frames[u]);
      gyro_dph[u] = streams[u].last_mean_dph();
      b.next[u] = 0;
    }
    const double air_c = world->air_c();
    std::lock_guard lock(mutex);
    chamber->show({.process_value_c = pv_c,
                   .freeze_pv = faults.freeze_pv,
                   .heating = running && commanded - air_c > at_setpoint_band_c,
                   .cooling = running && air_c - commanded > at_setpoint_band_c,
                   .at_setpoint = running && std::abs(commanded - air_c) <= at_setpoint_band_c,
                   .alarm = faults.alarm});
    snap.time_s = world->time_s();
    snap.setpoint_c = setpoint_c;
    snap.running = running;
    snap.air_c = air_c;
    if (!faults.freeze_pv) snap.pv_c = pv_c;
    for (std::size_t u = 0; u < cfg.units.size(); ++u) {
      const auto s = world->sample(u);
      thermistors->show(u, 1, s.t1_c, faults.units[u].open_t1);
      thermistors->show(u, 2, s.t2_c, faults.units[u].open_t2);
      auto& us = snap.units[u];
      us.t1_c = s.t1_c;
      us.t2_c = s.t2_c;
      us.true_t1_c = world->true_t1_c(u);
      us.true_t2_c = world->true_t2_c(u);
      us.gyro_dph = gyro_dph[u];
      us.powered = streams[u].powered();
      us.powered_on_at_s = streams[u].powered_on_at_s();
    }
  }

  // Sends the frames of the current second due by `until`, with the loss and corruption the
  // faults ask for (a lost frame still uses its sequence number: the reader sees the gap).
  template <class Due>
  void emit(Batch& b, SteadyClock::time_point until, Due&& due, std::mt19937_64& rng, std::vector<::can_frame>& out) {
    out.clear();
    std::uniform_real_distribution<double> uniform(0.0, 1.0);
    {
      std::lock_guard lock(mutex);
      for (std::size_t u = 0; u < b.frames.size(); ++u) {
        auto& f = faults.units[u];
        auto& st = snap.units[u];
        while (b.next[u] < b.frames[u].size() && (until == SteadyClock::time_point::max() || due(u, b.next[u]) <= until)) {
          const StreamFrame slot = b.frames[u][b.next[u]++];
          if (!slot.powered) continue;  // no power, no frame
          const std::int32_t counts = slot.counts;
          const std::uint8_t seq = slot.sequence;
          ++st.frames_sent;
          if (f.lose_burst > 0 || (f.lose_fraction > 0 && uniform(rng) < f.lose_fraction)) {
            if (f.lose_burst > 0) --f.lose_burst;
            ++st.frames_lost;
            continue;
          }
          ::can_frame frame = drivers::can::encode({cfg.units[u].gyro.node_id, counts, seq, drivers::can::status::valid});
          if (f.corrupt_fraction > 0 && uniform(rng) < f.corrupt_fraction) {
            // One bit of bytes 0..6: CRC-8 detects every single-bit error.
            const auto bit = std::uniform_int_distribution<int>(0, 55)(rng);
            frame.data[bit / 8] ^= static_cast<std::uint8_t>(1u << (bit % 8));
            ++st.frames_corrupted;
          }
          out.push_back(frame);
        }
      }
    }
    send_frames(out);
  }

  void stop_clock() {
    stopping = true;
    cv.notify_all();
    done_cv.notify_all();
    if (clock_thread.joinable()) clock_thread.join();
  }

  // ===== the server loop ======================================================================

  int run() {
    clock_thread = std::thread([this] { clock_loop(); });
    enum class Kind { signal, wake, listener, can, control, modbus_client, control_client };
    struct Entry {
      Kind kind;
      std::size_t index;
    };
    std::vector<pollfd> fds;
    std::vector<Entry> what;
    while (!stop_requested) {
      fds.clear();
      what.clear();
      auto add = [&](int fd, short events, Kind k, std::size_t i) {
        fds.push_back({fd, events, 0});
        what.push_back({k, i});
      };
      add(signal_fd, POLLIN, Kind::signal, 0);
      add(wake_fd, POLLIN, Kind::wake, 0);
      for (std::size_t i = 0; i < listeners.size(); ++i) {
        if (listeners[i].fd >= 0) add(listeners[i].fd, POLLIN, Kind::listener, i);
      }
      add(can_fd, POLLIN, Kind::can, 0);
      if (control_fd >= 0) add(control_fd, POLLIN, Kind::control, 0);
      auto timeout = SteadyClock::time_point::max();
      for (std::size_t i = 0; i < modbus_clients.size(); ++i) {
        const auto& c = modbus_clients[i];
        if (c.fd < 0) continue;
        add(c.fd, c.pending ? 0 : POLLIN, Kind::modbus_client, i);
        if (c.pending) timeout = std::min(timeout, c.due);
      }
      for (std::size_t i = 0; i < control_clients.size(); ++i) {
        const auto& c = control_clients[i];
        if (c.fd >= 0) add(c.fd, static_cast<short>(POLLIN | (c.out.empty() ? 0 : POLLOUT)), Kind::control_client, i);
      }
      int timeout_ms = 1000;
      if (timeout != SteadyClock::time_point::max()) {
        const auto left = std::chrono::ceil<std::chrono::milliseconds>(timeout - SteadyClock::now()).count();
        timeout_ms = static_cast<int>(std::clamp<std::int64_t>(left, 0, 1000));
      }
      if (::poll(fds.data(), fds.size(), timeout_ms) < 0 && errno != EINTR) {
        spdlog::error("poll: {}", errno_text(errno));
        break;
      }
      for (std::size_t i = 0; i < fds.size() && !stop_requested; ++i) {
        if (fds[i].revents == 0) continue;
        const auto [kind, idx] = what[i];
        switch (kind) {
          case Kind::signal: {
            signalfd_siginfo si{};
            if (::read(signal_fd, &si, sizeof si) == sizeof si) {
              request_stop(si.ssi_signo == SIGINT ? "SIGINT" : "SIGTERM");
            }
            break;
          }
          case Kind::wake: {
            std::uint64_t n = 0;
            [[maybe_unused]] auto r = ::read(wake_fd, &n, sizeof n);
            break;
          }
          case Kind::listener:
            if (listeners[idx].fd == fds[i].fd) accept_modbus(idx);
            break;
          case Kind::can: accept_can(); break;
          case Kind::control: accept_control(); break;
          case Kind::modbus_client: {
            auto& c = modbus_clients[idx];
            if (c.fd != fds[i].fd) break;  // closed meanwhile (a drop fault)
            if (c.pending) {
              if (fds[i].revents & (POLLHUP | POLLERR)) close_client(c, "hung up");
            } else {
              read_request(c);
            }
            break;
          }
          case Kind::control_client: {
            auto& c = control_clients[idx];
            if (c.fd != fds[i].fd) break;
            if (fds[i].revents & POLLOUT) flush_control(c);
            if (c.fd >= 0 && (fds[i].revents & (POLLIN | POLLHUP | POLLERR))) read_control(c);
            break;
          }
        }
      }
      serve_due_replies(SteadyClock::now());
      std::erase_if(modbus_clients, [](const ModbusClient& c) { return c.fd < 0; });
      std::erase_if(control_clients, [](const ControlClient& c) { return c.fd < 0; });
    }
    // Let the last replies (the "stop" command's own) go out before the sockets close.
    for (auto& c : control_clients) {
      if (c.fd >= 0) flush_control(c);
    }
    stop_clock();
    {
      std::lock_guard lock(mutex);
      spdlog::info("stopped at simulated time {} s", snap.time_s);
    }
    close_all();
    return 0;
  }
};

Bench::Bench(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Bench::~Bench() = default;

std::expected<std::unique_ptr<Bench>, std::string> Bench::create(BenchConfig config) {
  auto impl = std::make_unique<Impl>();
  impl->cfg = std::move(config);
  if (auto ok = impl->init(); !ok) return std::unexpected(ok.error());
  return std::unique_ptr<Bench>(new Bench(std::move(impl)));
}

json Bench::ready_line() const {
  const auto& c = impl_->cfg;
  json units = json::array();
  for (const auto& u : c.units) {
    units.push_back({{"serial", u.serial},
                     {"node_id", u.gyro.node_id},
                     {"mode", u.gyro.mode == drivers::GyroMode::rate ? "rate" : "increment"},
                     {"frame_rate_hz", u.frame_rate_hz}});
  }
  return {{"event", "ready"},
          {"version", control_protocol_version},
          {"pid", ::getpid()},
          {"time_scale", c.time_scale},
          {"seed", c.sim.seed},
          {"chamber", {{"host", c.where.host}, {"port", c.where.chamber_port}, {"unit_id", c.where.chamber_unit},
                       {"map", c.map.map.name}}},
          {"thermistors", {{"host", c.where.host}, {"port", c.where.thermistor_port}, {"unit_id", c.where.thermistor_unit}}},
          {"can_socket", c.where.can_socket},
          {"control", c.control_path.empty() ? json(nullptr) : json(c.control_path)},
          {"units", units},
          {"drivers_config", drivers_config(c.where, c.map, c.units)}};
}

int Bench::run() { return impl_->run(); }

}  // namespace fogbench::mock
