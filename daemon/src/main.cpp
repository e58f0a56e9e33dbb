// fogbenchd: the bench daemon. Runs in the foreground, logs to stderr, stops on SIGTERM.
#include <CLI/CLI.hpp>
#include <cmath>
#include <iostream>

#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include "fogbench/daemon/config.hpp"
#include "fogbench/daemon/server.hpp"

int main(int argc, char** argv) {
  CLI::App app{"fogbenchd: the fogbench bench daemon (fogbench " FOGBENCH_DAEMON_VERSION ")"};
  std::string config_path;
  double time_scale = 1.0;
  std::string log_level = "info";
  app.add_option("-c,--config", config_path, "configuration file (JSON, see docs/daemon.md)")->required();
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

  // Logs go to stderr: stdout carries only the one "ready" line.
  auto logger = spdlog::stderr_color_mt("fogbenchd");
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
  fogbench::daemon::Server server(std::move(*config), {time_scale});
  if (auto ok = server.start(); !ok) {
    spdlog::error("{}", ok.error().message);
    return ok.error().exit_code;
  }
  return server.run();
}
