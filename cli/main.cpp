// fogctl: the command-line client of fogbench and its offline analysis tool.
#include <malloc.h>

#include <CLI/CLI.hpp>
#include <iostream>

#include "client.hpp"
#include "common.hpp"
#include "offline.hpp"
#include "workbench.hpp"

int main(int argc, char** argv) {
  // fogctl is short-lived and works on arrays of a run's length (MBs each): keep freed memory
  // in the heap instead of returning it to the kernel and faulting it in again, which cost a
  // third of `fogctl fit` on a day's run.
  mallopt(M_MMAP_THRESHOLD, 256 << 20);
  mallopt(M_TRIM_THRESHOLD, 512 << 20);
  CLI::App app{"fogctl: fibre-optic gyro thermal-drift qualification (fogbench " FOGBENCH_VERSION ")"};
  app.set_version_flag("--version", std::string(FOGBENCH_VERSION));
  app.require_subcommand(1);
  int code = fogbench::cli::kExitOk;
  fogbench::cli::add_offline_commands(app, code);
  fogbench::cli::add_client_commands(app, code);
  fogbench::cli::add_workbench_commands(app, code);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // --help and --version exit 0; a usage error exits 2 with CLI11's message.
    const int rc = app.exit(e);
    return rc == 0 ? 0 : fogbench::cli::kExitError;
  }
  return code;
}
