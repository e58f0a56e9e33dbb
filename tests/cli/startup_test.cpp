// fogctl's start-up (issue 30): the offline commands never load the PostgreSQL client; the fleet
// commands run in fogctl-fleet, which does. What the dynamic loader actually opens is read from
// its own trace (glibc's LD_DEBUG=files: one "file=NAME" line per object loaded, dlopen included).
#include <sys/wait.h>

#include <catch2/catch.hpp>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "common.hpp"
#include "fogctl_process.hpp"
#include "offline.hpp"

using namespace fogbench::cli;
using namespace fogbench::cli::testing;
namespace fs = std::filesystem;
using Catch::Contains;

namespace {

const std::string fogctl_exe = std::string(FOGBENCH_BIN_DIR) + "/fogctl";

}  // namespace

TEST_CASE("fogctl: offline commands load no PostgreSQL client, fleet commands load it in fogctl-fleet") {
  Dir d("fogctl-startup");
  SimulateOptions s;
  s.profile = "exp1";
  s.seed = 1;
  s.output = d.file("exp1.csv");
  s.quiet = true;
  std::ostringstream so, se;
  REQUIRE(run_simulate(s, so, se) == kExitOk);

  const Ran version = run(d, fogctl_exe, "--version", "LD_DEBUG=files");
  CHECK(version.code == 0);
  CHECK(version.out == std::string(FOGBENCH_VERSION) + "\n");
  // The trace is there (the check below is not vacuous): the C library and FFTW are loaded ...
  CHECK_THAT(version.err, Contains("file=libc.so.6") && Contains("file=libfftw3"));
  // ... and no libpq, nor what only libpq brings (Kerberos, LDAP).
  CHECK_THAT(version.err, !Contains("libpq") && !Contains("libkrb5") && !Contains("libldap"));

  const Ran fit = run(d, fogctl_exe, "fit '" + d.file("exp1.csv") + "' -o '" + d.file("model.json") + "'", "LD_DEBUG=files");
  CHECK(fit.code == 0);
  CHECK(fs::exists(d.file("model.json")));
  CHECK_THAT(fit.err, Contains("file=libc.so.6") && !Contains("libpq"));

  // A fleet command runs in fogctl-fleet (its own error, from run_fleet), which loads libpq.
  const Ran fleet = run(d, fogctl_exe, "fleet serials", "LD_DEBUG=files");
  CHECK(fleet.code == kExitError);
  CHECK_THAT(fleet.err, Contains("fogctl fleet serials: give the plant store with exactly one of --db CONNSTR or --service NAME"));
  CHECK_THAT(fleet.err, Contains("file=libpq.so"));
  // Its options are parsed as fogctl parses them, fogctl's global --wide included.
  const Ran wide = run(d, fogctl_exe, "--wide fleet dist --by lot --figure T1");
  CHECK(wide.code == kExitError);
  CHECK_THAT(wide.err, Contains("fogctl fleet dist: give the plant store"));
  // --help lists the fleet commands in fogctl itself.
  const Ran help = run(d, fogctl_exe, "fleet --help");
  CHECK(help.code == 0);
  CHECK_THAT(help.out, Contains("serials") && Contains("spc"));
}

TEST_CASE("fogctl: without fogctl-fleet beside it, a fleet command names the program and the paths tried") {
  Dir d("fogctl-startup");
  const fs::path copy = d.path / "bin" / "fogctl";
  fs::create_directories(copy.parent_path());
  fs::copy_file(fogctl_exe, copy);
  const Ran fleet = run(d, copy.string(), "fleet serials --db 'dbname=plant'");
  CHECK(fleet.code == kExitError);
  CHECK_THAT(fleet.err, Contains("fogctl-fleet") && Contains("libpq") && Contains("cannot be executed"));
  CHECK_THAT(fleet.err, Contains((d.path / "bin" / "fogctl-fleet").string() + ": No such file or directory"));
  CHECK_THAT(fleet.err, Contains((d.path / "libexec" / "fogbench" / "fogctl-fleet").string()));
  // The offline commands do not need it.
  const Ran version = run(d, copy.string(), "--version");
  CHECK(version.code == 0);
}
