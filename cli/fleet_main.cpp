// fogctl-fleet: fogctl's fleet commands (fleet.hpp), the only ones that need the PostgreSQL
// client. fogctl executes it with its own arguments (`fogctl fleet ...`), so it parses the same
// command line as fogctl would: the fleet command and fogctl's global options.
#include <CLI/CLI.hpp>
#include <iostream>

#include "common.hpp"
#include "fleet.hpp"
#include "help_format.hpp"
#include "table.hpp"

int main(int argc, char** argv) {
  CLI::App app{"fogctl: fibre-optic gyro thermal-drift qualification (fogbench " FOGBENCH_VERSION "), fleet commands",
               "fogctl"};
  app.formatter(fogbench::cli::wrapping_help_formatter());  // before the commands: they inherit it
  app.set_version_flag("--version", std::string(FOGBENCH_VERSION));
  app.require_subcommand(1);
  app.fallthrough();
  app.add_flag_callback("--wide", [] { fogbench::cli::set_output_width(0); },
                        "Print tables with whole lines, however wide");
  int code = fogbench::cli::kExitOk;
  fogbench::cli::add_fleet_command(app, code, [](const std::string& command, const fogbench::cli::FleetOptions& o) {
    return fogbench::cli::run_fleet(command, o, std::cout, std::cerr);
  });
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int rc = app.exit(e);
    return rc == 0 ? 0 : fogbench::cli::kExitError;
  }
  return code;
}
