// fogctl: the command-line client of fogbench and its offline analysis tool.
#include <malloc.h>
#include <sys/mman.h>
#include <unistd.h>

#include <cstdint>
#include <cstdlib>

#include <CLI/CLI.hpp>
#include <iostream>

#include "allan.hpp"
#include "client.hpp"
#include "cert.hpp"
#include "coefficients.hpp"
#include "common.hpp"
#include "fleet.hpp"
#include "help_format.hpp"
#include "offline.hpp"
#include "plan.hpp"
#include "scale_factor.hpp"
#include "table.hpp"
#include "workbench.hpp"

int main(int argc, char** argv) {
  // fogctl is short-lived and works on arrays of a run's length (MBs each): keep freed memory
  // in the heap instead of returning it to the kernel and faulting it in again, which cost a
  // third of `fogctl fit` on a day's run.
  mallopt(M_MMAP_THRESHOLD, 256 << 20);
  mallopt(M_TRIM_THRESHOLD, 512 << 20);
  // One heap for every thread: diagnose and report refit on both cores and read the floor and
  // the periodic search beside them, and an arena per thread kept each one's freed columns
  // apart from the others' (never trimmed, above). The allocations are few and large, so the
  // shared lock costs nothing measurable; a 3-day diagnose's peak fell from 456 to 302 MB.
  mallopt(M_ARENA_MAX, 1);
  // ... and back the heap with transparent huge pages where the kernel offers them on request
  // (madvise mode, Debian's default): 2 MB pages cut the page faults of a day's run from
  // ~6,800 to ~900. The heap is grown once by 64 MB so the advice covers what a fit uses.
  mallopt(M_TOP_PAD, 64 << 20);
  if (void* probe = std::malloc(32u << 20)) {  // grows the heap: 32 MB plus the 64 MB pad
    constexpr std::uintptr_t huge = 2u << 20;
    const auto lo = (reinterpret_cast<std::uintptr_t>(probe) + huge - 1) & ~(huge - 1);
    const auto hi = reinterpret_cast<std::uintptr_t>(sbrk(0));
    if (hi > lo) madvise(reinterpret_cast<void*>(lo), hi - lo, MADV_HUGEPAGE);  // advice only: failure is harmless
    std::free(probe);  // kept in the heap (trim threshold above), untouched until used
  }
  CLI::App app{"fogctl: fibre-optic gyro thermal-drift qualification (fogbench " FOGBENCH_VERSION ")"};
  // Before the commands: each inherits the formatter when it is made.
  app.formatter(fogbench::cli::wrapping_help_formatter());
  app.set_version_flag("--version", std::string(FOGBENCH_VERSION));
  app.require_subcommand(1);
  // Human tables fit the terminal (cli/table.hpp: wrapped text columns); --wide prints whole
  // lines. Given anywhere on the line: the commands' unmatched options fall through to here.
  app.fallthrough();
  app.add_flag_callback("--wide", [] { fogbench::cli::set_output_width(0); },
                        "Print tables with whole lines, however wide (default: fit the terminal's width, "
                        "or $COLUMNS; piped output keeps whole lines)");
  int code = fogbench::cli::kExitOk;
  fogbench::cli::add_offline_commands(app, code);
  fogbench::cli::add_client_commands(app, code);
  fogbench::cli::add_workbench_commands(app, code);
  fogbench::cli::add_allan_command(app, code);
  fogbench::cli::add_coefficients_command(app, code);
  fogbench::cli::add_scale_factor_command(app, code);
  fogbench::cli::add_cert_command(app, code);
  fogbench::cli::add_plan_commands(app, code);
  // The fleet commands run in fogctl-fleet, which links libpq: fogctl never loads it (fleet.hpp).
  fogbench::cli::add_fleet_command(app, code, [argv](const std::string&, const fogbench::cli::FleetOptions&) {
    return fogbench::cli::run_fleet_program(argv, std::cerr);
  });
  fogbench::cli::add_profile_commands(app, code);
  fogbench::cli::add_store_commands(app, code);
  fogbench::cli::add_stored_run_options(app);  // after the commands it extends
  fogbench::cli::add_generate_command(app, code);  // last: it walks the whole table
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // --help and --version exit 0; a usage error exits 2 with CLI11's message.
    const int rc = app.exit(e);
    return rc == 0 ? 0 : fogbench::cli::kExitError;
  }
  return code;
}
