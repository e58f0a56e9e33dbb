// The mock bench put together (see bench.hpp): the configuration checked, the shared state set
// up, the control socket and the signals handled, and the server loop that polls the parts.
// The parts are apart: ModbusServer (modbus_server.hpp), CanBus (can_bus.hpp) and BenchClock
// (bench_clock.hpp), meeting only in SharedState (shared_state.hpp); the control socket is a
// LineServer (line_server.hpp) answered by handle_line (control.hpp).
#include "bench.hpp"

#include <signal.h>
#include <spdlog/spdlog.h>
#include <sys/eventfd.h>
#include <sys/signalfd.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>

#include "bench_clock.hpp"
#include "can_bus.hpp"
#include "control.hpp"
#include "faults.hpp"
#include "line_server.hpp"
#include "modbus_server.hpp"
#include "poll_set.hpp"
#include "serial_gyro.hpp"
#include "shared_state.hpp"
#include "unix_socket.hpp"

namespace fogbench::mock {

using nlohmann::json;
using SteadyClock = std::chrono::steady_clock;

struct Bench::Impl final : ControlHandler {
  BenchConfig cfg;
  std::vector<std::string> serials;
  SharedState shared;
  CanBus can;
  SerialGyroPeer serial_gyro;  // before the clock: the clock thread writes to it
  std::optional<ModbusServer> modbus;
  std::optional<AsciiChamberServer> ascii;  // the chamber, when its dialect is not Modbus
  std::optional<RateTableServer> table;     // --rate-table-port
  SteadyClock::time_point started = SteadyClock::now();
  std::optional<BenchClock> clock;

  // ---- the control socket and the loop's own descriptors (server loop only) ----
  std::optional<LineServer> control;  // --control: JSON lines, answered by handle_line
  int signal_fd = -1, wake_fd = -1;
  std::atomic<bool> stop_requested{false};
  sigset_t blocked{};

  ~Impl() override {
    if (clock) clock->stop();
    close_all();
  }

  // ===== set-up ===============================================================================

  std::expected<void, std::string> init() {
    for (const auto& u : cfg.units) serials.push_back(u.serial);
    if (cfg.sim.units.size() != cfg.units.size()) return std::unexpected(std::string("physics and layout disagree on the number of units"));
    if (!(cfg.time_scale > 0) || cfg.time_scale > 100000) return std::unexpected(std::string("--time-scale must be in (0, 100000]"));
    clock.emplace(cfg, shared, can, [this] { request_stop("duration reached"); });
    if (auto ok = clock->init(); !ok) return ok;

    auto ch = ChamberRegisters::create(cfg.map.map, cfg.sim.start_c, true);
    if (!ch) return std::unexpected("chamber map: " + ch.error());
    shared.chamber.emplace(std::move(*ch));
    auto th = ThermistorRegisters::create(cfg.units);
    if (!th) return std::unexpected("thermistor module: " + th.error());
    shared.thermistors.emplace(std::move(*th));
    shared.faults.units.assign(cfg.units.size(), {});
    auto& snap = shared.snap;
    snap.time_s = 0;
    snap.setpoint_c = snap.air_c = snap.pv_c = cfg.sim.start_c;
    snap.units.assign(cfg.units.size(), {});
    for (std::size_t u = 0; u < cfg.units.size(); ++u) {
      for (int s : {1, 2}) shared.thermistors->show(u, s, cfg.sim.start_c, false);
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

    modbus.emplace(shared, cfg.where);
    if (cfg.dialect == ChamberDialect::modbus) {
      if (auto ok = modbus->open(cfg.gateway); !ok) return ok;
      cfg.where.chamber_port = modbus->chamber_port();
    } else {
      if (cfg.gateway) return std::unexpected(std::string("--gateway needs the modbus chamber dialect"));
      ascii.emplace(shared, cfg.dialect, cfg.where.host, cfg.where.chamber_port);
      if (auto ok = ascii->open(); !ok) return ok;
      cfg.where.chamber_port = ascii->port();
      if (auto ok = modbus->open(false, false); !ok) return ok;
    }
    cfg.where.thermistor_port = modbus->thermistor_port();
    if (cfg.rate_table_port) {
      shared.rate_table.emplace();
      // Called under the shared mutex. Free-running, the bench's time is the wall clock times the
      // scale; paced, it is the simulated time the clock has reached (it moves only on advance).
      table.emplace(shared, cfg.where.host, *cfg.rate_table_port, [this] {
        if (cfg.paced) return shared.snap.time_s;
        return cfg.time_scale * std::chrono::duration<double>(SteadyClock::now() - started).count();
      });
      if (auto ok = table->open(); !ok) return ok;
      cfg.rate_table_port = table->port();
    }

    if (auto ok = can.listen(cfg.where.can_socket); !ok) return std::unexpected("CAN socket " + ok.error());
    if (!cfg.serial_gyro_link.empty()) {
      const auto& gyro = cfg.units.at(0).gyro;
      if (gyro.mode != drivers::GyroMode::rate) {
        return std::unexpected(std::string("--serial-gyro: the first unit's gyro must be in rate mode"));
      }
      if (auto ok = serial_gyro.open(cfg.serial_gyro_link, *cfg.serial_frame, gyro.node_id, gyro.scale_dph_per_count); !ok) {
        return std::unexpected("--serial-gyro: " + ok.error());
      }
      can.tap(&serial_gyro);
    }
    if (!cfg.control_path.empty()) {
      const auto too_long =
          json{{"ok", false}, {"error", "request longer than " + std::to_string(max_control_line) + " bytes"}}.dump() + "\n";
      control.emplace("control socket", LineServer::UnixPath{cfg.control_path},
                      [this](const std::string& line) { return LineServer::Reply{handle_line(line, *this) + "\n"}; },
                      LineServer::Options{.lf_only = true, .overflow_reply = too_long});
      if (auto ok = control->open(); !ok) return std::unexpected("control socket " + ok.error());
    }
    for (const auto& f : cfg.start_faults) {
      if (auto ok = fault(f); !ok) return std::unexpected("--fault " + f.value("name", std::string("?")) + ": " + ok.error());
    }
    // Before the first simulated second the status says what the start's faults make of it: a
    // unit powered off from 0 s (--fault power_off=D) is off, not the streams' initial on (a
    // status asked that early, on a busy host, said powered with a rate).
    for (std::size_t u = 0; u < snap.units.size(); ++u) {
      const auto& f = shared.faults.units[u];
      snap.units[u].powered = PowerWindow{f.power_off_from_s, f.power_on_at_s}.powered_at(snap.time_s);
    }
    return {};
  }

  void close_all() {
    if (modbus) modbus->close();
    if (ascii) ascii->close();
    if (table) table->close();
    if (control) control->close();
    can.close();
    can.tap(nullptr);
    serial_gyro.close();
    for (int* fd : {&signal_fd, &wake_fd}) {
      if (*fd >= 0) ::close(*fd);
      *fd = -1;
    }
  }

  // ===== control handler (called on the server loop) ==========================================

  std::expected<void, std::string> fault(const json& command) override {
    auto cmd = parse_fault_command(command, serials);
    if (!cmd) return std::unexpected(cmd.error());
    if (!table && (cmd->kind == FaultKind::table_fault || cmd->kind == FaultKind::drop_table)) {
      return std::unexpected(std::string(to_string(cmd->kind)) + ": no rate table is served (--rate-table-port)");
    }
    if (cmd->kind == FaultKind::silence_axis && cmd->axis) {
      // An axis the unit does not have cannot be silenced: said, not ignored.
      for (std::size_t u = 0; u < cfg.units.size(); ++u) {
        if (cmd->unit && *cmd->unit != u) continue;
        if (*cmd->axis >= cfg.units[u].gyro.axes) {
          return std::unexpected("silence_axis: axis " + std::string(1, "xyz"[*cmd->axis]) + ": unit " + cfg.units[u].serial +
                                 " has " + std::to_string(cfg.units[u].gyro.axes) +
                                 " axis (start the bench with --axes 3 for three-axis units)");
        }
      }
    }
    const bool serial_fault = cmd->kind == FaultKind::serial_garbage || cmd->kind == FaultKind::serial_cut ||
                              cmd->kind == FaultKind::serial_bad_crc || cmd->kind == FaultKind::serial_baud;
    if (serial_fault && cfg.serial_gyro_link.empty()) {
      return std::unexpected(std::string(to_string(cmd->kind)) + ": the bench serves no serial gyro (start it with --serial-gyro)");
    }
    SerialLineFaults serial_faults;
    {
      std::lock_guard lock(shared.mutex);
      auto& faults = shared.faults;
      apply_fault(faults, *cmd, shared.snap.time_s);
      serial_faults = faults.serial;
      // Register-level faults show at once, so a client reading right after the reply sees them.
      shared.chamber->show_alarm(faults.alarm);
      for (std::size_t u = 0; u < faults.units.size(); ++u) {
        shared.thermistors->show(u, 1, shared.snap.units[u].t1_c, faults.units[u].open_t1);
        shared.thermistors->show(u, 2, shared.snap.units[u].t2_c, faults.units[u].open_t2);
      }
    }
    // Outside the shared lock: the clock thread writes frames to the peer (its own lock).
    if (serial_fault) serial_gyro.set_faults(serial_faults);
    if (cmd->kind == FaultKind::refuse_modbus) modbus->update_listeners();
    if (cmd->kind == FaultKind::drop_modbus && cmd->on) modbus->drop_clients(cmd->device);
    if (ascii && cmd->kind == FaultKind::refuse_modbus) ascii->update_listener();
    if (ascii && cmd->kind == FaultKind::drop_modbus && cmd->on && cmd->device != Device::thermistors) {
      ascii->drop_clients();
    }
    spdlog::info("fault {} {}: {}", to_string(cmd->kind), cmd->on ? "on" : "off", command.dump());
    return {};
  }

  json status() override {
    json out;
    {
      std::lock_guard lock(shared.mutex);
      const auto& snap = shared.snap;
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
        if (cfg.units[i].gyro.axes != 1) {
          units.back()["axes"] = cfg.units[i].gyro.axes;
          units.back()["axis_gyro_dph"] = u.axis_gyro_dph;  // axes 1, 2
          units.back()["axes_frames"] = {{"sent", u.axes_frames_sent}, {"lost", u.axes_frames_lost},
                                         {"corrupted", u.axes_frames_corrupted}};
        }
      }
      out["units"] = std::move(units);
      out["faults"] = active_faults(shared.faults, serials, snap.time_s);
    }
    out["modbus_clients"] = modbus->open_clients();
    if (ascii) out["chamber_clients"] = ascii->open_clients();
    if (table) {
      std::lock_guard lock(shared.mutex);
      const auto& t = *shared.rate_table;
      out["rate_table"] = {{"time_s", t.time_s()}, {"rate_dps", t.rate_dps()}, {"position_deg", t.position_deg()},
                           {"fault", t.fault()}, {"clients", table->open_clients()}};
    }
    out["can_clients"] = can.readers();
    out["can_frames_dropped"] = can.dropped();
    return out;
  }

  void stop() override { request_stop("stop command"); }

  std::expected<double, std::string> advance(std::int64_t seconds) override { return clock->advance(seconds); }

  void request_stop(const char* why) {
    if (!stop_requested.exchange(true)) spdlog::info("stopping: {}", why);
    const std::uint64_t one = 1;
    [[maybe_unused]] auto n = ::write(wake_fd, &one, sizeof one);
  }

  // ===== the server loop ======================================================================

  void watch_own(PollSet& set) {
    set.add(signal_fd, POLLIN, [this](short) {
      signalfd_siginfo si{};
      if (::read(signal_fd, &si, sizeof si) == sizeof si) request_stop(si.ssi_signo == SIGINT ? "SIGINT" : "SIGTERM");
    });
    set.add(wake_fd, POLLIN, [this](short) {
      std::uint64_t n = 0;
      [[maybe_unused]] auto r = ::read(wake_fd, &n, sizeof n);
    });
    set.add(can.fd(), POLLIN, [this](short) { can.accept(); });
    if (control) (void)control->watch(set);  // its replies are never held back
  }

  int run() {
    clock->start();
    started = SteadyClock::now();  // the rate table's time 0
    PollSet set;
    while (!stop_requested) {
      set.clear();
      watch_own(set);
      auto due = modbus->watch(set);
      if (ascii) due = std::min(due, ascii->watch(set));
      if (table) table->watch(set);
      int timeout_ms = 1000;
      if (due != SteadyClock::time_point::max()) {
        const auto left = std::chrono::ceil<std::chrono::milliseconds>(due - SteadyClock::now()).count();
        timeout_ms = static_cast<int>(std::clamp<std::int64_t>(left, 0, 1000));
      }
      if (!set.wait(timeout_ms)) {
        spdlog::error("poll: {}", errno_text(errno));
        break;
      }
      set.dispatch([this] { return !stop_requested.load(); });
      modbus->after_round(SteadyClock::now());
      if (ascii) ascii->after_round(SteadyClock::now());
    }
    // Let the last replies (the "stop" command's own) go out before the sockets close.
    if (control) control->flush();
    clock->stop();
    {
      std::lock_guard lock(shared.mutex);
      spdlog::info("stopped at simulated time {} s", shared.snap.time_s);
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

namespace {

// The drivers configuration that reads what is served: the Modbus one, with the chamber's
// section for its dialect when that is not Modbus.
json served_drivers_config(const BenchConfig& c) {
  json out = drivers_config(c.where, c.map, c.units);
  if (!c.startup_flag)
    for (auto& u : out["units"]) u["gyro"]["startup_flag"] = false;
  if (!c.serial_gyro_link.empty()) {
    // The first unit read on its serial line (the bus's copy of its frames is not taken from the
    // CAN socket: GyroBus leaves a unit with a line of its own out of the bus), the others on CAN.
    // Serial frames carry no power-on evidence.
    auto& u0 = out["units"][0];
    u0["gyro_line"] = {{"transport", "serial:" + c.serial_gyro_link + "?baud=" + std::to_string(default_serial_line_baud)},
                       {"frame", c.serial_frame_json}};
    u0["gyro"]["startup_flag"] = false;
  }
  if (c.dialect == ChamberDialect::modbus) return out;
  json chamber = {{"kind", to_string(c.dialect)},
                  {"link", {{"transport", "tcp"}, {"host", c.where.host}, {"port", c.where.chamber_port}}}};
  for (const char* k : {"pv_limits_c", "setpoint_limits_c"}) {
    if (out["chamber"].contains(k)) chamber[k] = out["chamber"][k];
  }
  out["chamber"] = std::move(chamber);
  return out;
}

}  // namespace

json Bench::ready_line() const {
  const auto& c = impl_->cfg;
  json units = json::array();
  for (const auto& u : c.units) {
    units.push_back({{"serial", u.serial},
                     {"node_id", u.gyro.node_id},
                     {"mode", u.gyro.mode == drivers::GyroMode::rate ? "rate" : "increment"},
                     {"frame_rate_hz", u.frame_rate_hz}});
    if (u.gyro.axes != 1) {
      units.back()["axes"] = u.gyro.axes;
      units.back()["axis_bias_dph"] = u.axis_bias_dph;  // per axis, added to the unit's drift
      const auto& p = c.sim.units[units.size() - 1];
      const auto& own = p.axis_effects;
      if (!own[0].empty() || !own[1].empty() || !p.x_effects.empty())
        units.back()["axis_effects"] = {{"x", p.x_effects}, {"y", own[0]}, {"z", own[1]}};
      units.back()["axis_thermistors"] = p.axis_coils.has_value();
    }
  }
  return {{"event", "ready"},
          {"version", control_protocol_version},
          {"pid", ::getpid()},
          {"time_scale", c.time_scale},
          {"seed", c.sim.seed},
          {"chamber", {{"host", c.where.host}, {"port", c.where.chamber_port}, {"unit_id", c.where.chamber_unit},
                       {"map", c.map.map.name}, {"dialect", to_string(c.dialect)}}},
          {"thermistors", {{"host", c.where.host}, {"port", c.where.thermistor_port}, {"unit_id", c.where.thermistor_unit}}},
          {"can_socket", c.where.can_socket},
          {"serial_gyro", c.serial_gyro_link.empty() ? json(nullptr) : json(c.serial_gyro_link)},
          {"control", c.control_path.empty() ? json(nullptr) : json(c.control_path)},
          {"units", units},
          {"drivers_config", served_drivers_config(c)},
          // Not in drivers_config: fogbenchd reads it as its own rate_table section.
          {"rate_table_config", c.rate_table_port ? json{{"kind", "acutrol"},
                                                         {"link", {{"transport", "tcp"}, {"host", c.where.host},
                                                                   {"port", *c.rate_table_port}}},
                                                         {"max_rate_dps", served_table_max_rate_dps}}
                                                  : json(nullptr)},
          // What the table's rate becomes in the gyros' output (sim/scale_factor.hpp).
          {"scale_factor_truth", c.rate_table_port ? json{{"sf0", c.sf_truth.sf0},
                                                          {"t0_c", c.sf_truth.t0_c},
                                                          {"tc_ppm_per_c", c.sf_truth.tc_ppm_per_c},
                                                          {"tc2_ppm_per_c2", c.sf_truth.tc2_ppm_per_c2},
                                                          {"nl_ppm", c.sf_truth.nl_ppm},
                                                          {"full_scale_dps", c.sf_truth.full_scale_dps},
                                                          {"asymmetry_ppm", c.sf_truth.asymmetry_ppm},
                                                          {"coil", "true_t1_c"}}
                                                   : json(nullptr)}};
}

int Bench::run() { return impl_->run(); }

}  // namespace fogbench::mock
