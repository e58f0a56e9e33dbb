// fogbench-sim: the mock bench. Runs the bench's physics (sim::World) on a scaled clock and
// serves it as hardware: the chamber controller and the coil thermistor module over Modbus TCP,
// the gyros' CAN frames on a unix SEQPACKET socket, and a control socket for injecting faults.
// Prints one JSON line on stdout saying what it serves; logs go to stderr. docs/mock-bench.md.
#include <CLI/CLI.hpp>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <cstdio>
#include <iostream>

#include "bench.hpp"
#include "fogbench/console/text.hpp"
#include "options.hpp"

int main(int argc, char** argv) {
  using namespace fogbench::mock;
  Options o;
  int units = 0;
  std::string log_level = "info";
  CLI::App app{
      "fogbench-sim: the mock FOG bench. Serves the simulated chamber controller (Modbus TCP, map "
      "drivers/maps/mock.json), the coil thermistor module (Modbus TCP) and each unit's gyro CAN "
      "frames (unix SEQPACKET socket), stepped K times faster than real time. Prints one JSON line "
      "on stdout with what it serves, then runs until SIGINT/SIGTERM or {\"cmd\":\"stop\"}. See "
      "docs/mock-bench.md."};
  app.formatter(fogbench::console::wrapping_help_formatter());  // --help within the terminal
  app.add_option("--modbus-host", o.host, "IPv4 address the Modbus listeners bind")->capture_default_str();
  app.add_option("--modbus-port", o.modbus_port, "chamber controller's TCP port; 0: ephemeral (see the JSON line)")
      ->capture_default_str();
  app.add_option("--thermistor-port", o.thermistor_port, "thermistor module's TCP port; 0: ephemeral")->capture_default_str();
  app.add_flag("--gateway", o.gateway, "serve the thermistor module on the chamber's port under its own unit id");
  app.add_option("--chamber-unit", o.chamber_unit, "chamber's Modbus unit id")->capture_default_str();
  app.add_option("--thermistor-unit", o.thermistor_unit, "thermistor module's Modbus unit id")->capture_default_str();
  app.add_option("--can-socket", o.can_socket, "path of the AF_UNIX SOCK_SEQPACKET socket the gyro frames are served on")
      ->capture_default_str();
  app.add_option("--serial-gyro", o.serial_gyro,
                 "path of a link to a pty on which the first unit's frames are also served as binary serial frames "
                 "(with --serial-frame; docs/mock-bench.md)");
  app.add_option("--serial-frame", o.serial_frame, "JSON file of the serial frame layout, e.g. drivers/examples/kvh-1775-format-a.json");
  app.add_option("--control", o.control, "path of the control socket (newline-delimited JSON); none if not given");
  app.add_option("--units", units, "number of units under test, serials SIM-0001.. (default 2, or the --config file's)")
      ->check(CLI::Range(1, static_cast<int>(max_units)));
  app.add_option("--time-scale", o.time_scale, "simulated seconds per wall-clock second")->capture_default_str();
  app.add_option("--seed", o.seed, "seed of the physics and the frame noise")->capture_default_str();
  app.add_option("--effect", o.effects, "hidden drift effect in the term language, e.g. \"0.05*T1\"; every unit; repeatable")
      ->allow_extra_args(false);
  app.add_option("--coil", o.coil,
                 "coil model of every unit: distributed (radial layers, drift from the temperature field) or lumped "
                 "(two nodes, the paper's model is the exact truth); docs/simulation.md")
      ->capture_default_str();
  app.add_option("--start-c", o.start_c, "temperature of the chamber, coils and room at start, degC")->capture_default_str();
  app.add_option("--config", o.config_file, "JSON file of per-unit parameters (see docs/mock-bench.md)");
  app.add_option("--fault", o.faults, "fault active from the start: NAME[=VALUE][,KEY=VALUE...]; repeatable")
      ->allow_extra_args(false);
  app.add_option("--frame-rate-hz", o.frame_rate_hz, "gyro frames per simulated second, per unit")->capture_default_str();
  app.add_option("--axes", o.axes, "gyro axes per unit: 1, or 3 (axis k on node id + k, node ids 257 + 4i)")->capture_default_str();
  app.add_option("--axis-bias-dph", o.axis_bias_dph, "with --axes 3: 1 sigma of each y and z axis's own bias (seeded), deg/h")
      ->capture_default_str();
  app.add_option("--axis-effect", o.axis_effects,
                 "with --axes 3: drift of the y or z axis alone, AXIS=EXPR in the term language, e.g. \"y=0.5*T1\"; every unit; "
                 "repeatable");
  app.add_flag("--axis-thermistors", o.axis_thermistors,
               "with --axes 3: each axis a coil and thermistors of its own (the module's six channels per unit; y's and z's coils "
               "deeper in the housing, as fogctl simulate's); --axis-effect may then give x a drift of its own and read another "
               "axis's coil, e.g. \"x=0.3*T1y\"");
  app.add_option("--frame-noise-dph", o.frame_noise_dph,
                 "extra white noise per frame (1 sigma, deg/h), on top of the gyro's own noise made at the frame rate")
      ->capture_default_str();
  app.add_option("--warmup-dph", o.warmup_dph, "warm-up transient after each power-on, A in A*exp(-t/tau), deg/h; 0: none")
      ->capture_default_str();
  app.add_flag("--no-startup-flag", o.no_startup_flag,
               "a gyro kind without the warm-up status bit: no frame carries `warming_up` after a power-on (the counter "
               "still starts from 0); the drivers_config served says so (gyro.startup_flag false)");
  app.add_option("--warmup-tau-s", o.warmup_tau_s, "time constant tau of the warm-up, simulated s")->capture_default_str();
  app.add_option("--map", o.map_file, "serve another chamber register map (default: the built-in drivers/maps/mock.json)");
  app.add_option("--duration-s", o.duration_s, "stop after this many simulated seconds; 0: run until stopped")->capture_default_str();
  app.add_flag("--paced", o.paced,
               "the clock moves only when told ({\"cmd\":\"advance\"} on the control socket, which it needs): "
               "fogbenchd paces the world");
  app.add_option("--chamber-dialect", o.chamber_dialect,
                 "the chamber controller's protocol on --modbus-port: modbus (the map), espec (Espec P300/SCP-220 "
                 "ASCII) or simserv (Weiss/Voetsch SIMSERV); the thermistor module stays on Modbus")
      ->capture_default_str();
  app.add_option("--rate-table-port", o.rate_table_port,
                 "serve a single-axis rate table answering the ACUTROL command set on this TCP port (0: "
                 "ephemeral); the ready line's rate_table_config reads it");
  app.add_option("--log-level", log_level, "trace, debug, info, warn, error, off")->capture_default_str();
  app.set_version_flag("--version", std::string(FOGBENCH_SIM_VERSION));
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // --help is a "parse error" with status 0; every refused option exits 2, as ours do below.
    return app.exit(e) == 0 ? 0 : 2;
  }
  if (units > 0) o.units = units;

  auto logger = spdlog::stderr_color_mt("fogbench-sim");
  spdlog::set_default_logger(logger);
  spdlog::set_level(spdlog::level::from_str(log_level));

  auto cfg = make_bench_config(o);
  if (!cfg) {
    spdlog::error("{}", cfg.error());
    return 2;
  }
  auto bench = Bench::create(std::move(*cfg));
  if (!bench) {
    spdlog::error("{}", bench.error());
    return 1;
  }
  const auto ready = (*bench)->ready_line();
  spdlog::info("serving: chamber on {}:{} unit {}, thermistors on port {} unit {}, CAN on {}, {} unit(s) at time scale {}",
               ready["chamber"]["host"].get<std::string>(), ready["chamber"]["port"].get<int>(),
               ready["chamber"]["unit_id"].get<int>(), ready["thermistors"]["port"].get<int>(),
               ready["thermistors"]["unit_id"].get<int>(), ready["can_socket"].get<std::string>(),
               ready["units"].size(), ready["time_scale"].get<double>());
  std::cout << ready.dump() << std::endl;  // one line, flushed: scripts wait for it
  return (*bench)->run();
}
