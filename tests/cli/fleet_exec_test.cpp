// Where fogctl looks for fogctl-fleet (cli/fleet.hpp): beside itself, then at the installed place.
#include <catch2/catch.hpp>

#include "fleet.hpp"

using namespace fogbench::cli;

TEST_CASE("fleet program: looked for beside fogctl, then in libexec/fogbench relative to its folder") {
  const auto c = fleet_program_candidates("/opt/fb/bin/fogctl");
  REQUIRE(c.size() == 2);
  CHECK(c[0] == "/opt/fb/bin/fogctl-fleet");
  // GNUInstallDirs' defaults (bin, libexec): relative, so any prefix or DESTDIR finds it.
  CHECK(c[1] == "/opt/fb/libexec/fogbench/fogctl-fleet");
}
