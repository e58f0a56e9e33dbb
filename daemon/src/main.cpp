// fogbenchd: the bench daemon. Runs in the foreground, logs to stderr (to the journal in its
// format under systemd), stops on SIGTERM, reloads its configuration on SIGHUP; Type=notify:
// READY=1 once its sockets are bound, RELOADING=1 then READY=1 around a reload, STATUS= lines,
// WATCHDOG=1 while its event loop turns.
#include <CLI/CLI.hpp>
#include <chrono>
#include <cmath>
#include <fstream>
#include <iostream>
#include <sstream>
#include <optional>

#include <spdlog/spdlog.h>

#include "fogbench/console/text.hpp"
#include "fogbench/drivers/serial_devices.hpp"
#include "fogbench/daemon/config.hpp"
#include "fogbench/daemon/config_reload.hpp"
#include "fogbench/daemon/server.hpp"
#include "fogbench/daemon/systemd.hpp"
#include "watchdog.hpp"

namespace {

namespace sd = fogbench::daemon::systemd;

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"fogbenchd: the fogbench bench daemon (fogbench " FOGBENCH_DAEMON_VERSION ")"};
  app.formatter(fogbench::console::wrapping_help_formatter());  // --help within the terminal
  std::string config_path, check_path, device_allow_path;
  double time_scale = 1.0;
  std::string log_level = "info";
  app.add_option("-c,--config", config_path, "configuration file (JSON, see docs/daemon.md)");
  app.add_option("--check-config", check_path,
                 "validate a configuration file and exit: 0 valid, 2 invalid (the error names the key)");
  app.add_option("--device-allow", device_allow_path,
                 "print the systemd drop-in that lets the unit open the serial devices a configuration "
                 "file names (DeviceAllow= lines) and exit");
  app.add_option("--time-scale", time_scale,
                 "run the daemon clock K times faster (mock bench only: needs \"simulated\": true)");
  app.add_option("--log-level", log_level, "trace, debug, info, warn, error");
  app.set_version_flag("--version", std::string(FOGBENCH_DAEMON_VERSION));
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int rc = app.exit(e);
    return rc == 0 ? 0 : 2;
  }
  if (!check_path.empty()) {
    auto config = fogbench::daemon::load_daemon_config(check_path);
    if (!config) {
      std::cerr << "fogbenchd: " << config.error() << "\n";
      return 2;
    }
    // Paths as this machine has them: the syntax is right, but a folder that does not exist
    // would stop the daemon at start (issue 28).
    std::string text;
    {
      std::ifstream in(check_path);
      std::stringstream ss;
      ss << in.rdbuf();
      text = ss.str();
    }
    const auto problems = fogbench::daemon::config_path_problems(*config, text);
    for (const auto& p : problems) std::cerr << "fogbenchd: " << check_path << ": " << p << "\n";
    if (!problems.empty()) return 2;
    std::cout << check_path << ": valid\n";
    // The shipped unit allows /dev/ttyUSB* only: any other serial device would be refused
    // (EPERM) when the service opens it, though the file is valid.
    for (const auto& d : fogbench::drivers::serial_devices(config->drivers))
      if (!fogbench::drivers::allowed_by_shipped_unit(d.path))
        std::cout << "note: " << d.key << " " << d.path
                  << ": the shipped unit allows only /dev/ttyUSB* (DeviceAllow=char-ttyUSB); as a service, "
                     "allow it with the drop-in `fogbenchd --device-allow "
                  << check_path << "` prints\n";
    return 0;
  }
  if (!device_allow_path.empty()) {
    auto config = fogbench::daemon::load_daemon_config(device_allow_path);
    if (!config) {
      std::cerr << "fogbenchd: " << config.error() << "\n";
      return 2;
    }
    const auto devices = fogbench::drivers::serial_devices(config->drivers);
    if (devices.empty()) {
      std::cerr << "fogbenchd: " << device_allow_path
                << " names no serial device (its chamber and thermistor module are reached over TCP): no drop-in needed\n";
      return 0;
    }
    std::cout << fogbench::drivers::device_allow_dropin(devices, device_allow_path);
    return 0;
  }
  if (config_path.empty()) {
    std::cerr << "fogbenchd: --config is required (or --check-config FILE)\n"
              << "Run with --help for more information.\n";
    return 2;
  }

  // Logs go to stderr: stdout carries only the one "ready" line. Under the journal, lines in
  // its format (a priority, no second timestamp).
  auto logger = sd::stderr_logger("fogbenchd", sd::stderr_is_journal());
  spdlog::set_default_logger(logger);
  spdlog::set_level(spdlog::level::from_str(log_level));

  auto config = fogbench::daemon::load_daemon_config(config_path);
  if (!config) {
    spdlog::error("configuration: {}", config.error());
    return 2;
  }
  if (!std::isfinite(time_scale) || time_scale <= 0) {
    spdlog::error("--time-scale: expected a positive number");
    return 2;
  }
  if (time_scale != 1.0 && !config->simulated) {
    spdlog::error("--time-scale {} refused: the configuration does not say \"simulated\": true", time_scale);
    return 2;
  }
  const std::string socket_path = config->socket.unix_path.string();
  fogbench::daemon::Server server(std::move(*config), {time_scale, std::filesystem::absolute(config_path)});
  if (auto ok = server.start(); !ok) {
    sd::notify("STATUS=start-up failed: " + ok.error().message);
    spdlog::error("{}", ok.error().message);
    return ok.error().exit_code;
  }
  // The sockets are bound and the store is open: clients can connect (they wait in the
  // backlog until the loop accepts them).
  sd::notify("READY=1\nSTATUS=serving on " + socket_path);
  int rc = 0;
  {
    // WATCHDOG=1 only while the loop runs what is posted to it (watchdog.hpp).
    std::optional<fogbench::daemon::LoopWatchdog> watchdog;
    if (auto interval = sd::watchdog_interval())
      watchdog.emplace([&server](std::function<void()> task) { server.post(std::move(task)); },
                       [] { sd::notify("WATCHDOG=1"); }, *interval);
    rc = server.run();
  }
  sd::notify("STATUS=stopped (exit status " + std::to_string(rc) + ")");
  return rc;
}
