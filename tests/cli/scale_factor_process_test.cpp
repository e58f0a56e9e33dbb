// The built fogctl: `fogctl simulate --rate-sequence` then `fogctl scale-factor`, their --help,
// and their exit codes on bad input.
#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include "fogctl_process.hpp"

using namespace fogbench::cli::testing;
using Catch::Matchers::Contains;

TEST_CASE("fogctl scale-factor --help and simulate --help say the options and units", "[scale_factor][process]") {
  Dir d("sfp");
  auto h = fogctl(d, "scale-factor --help");
  CHECK(h.code == 0);
  CHECK_THAT(h.out, Contains("--settle") && Contains("--t0") && Contains("--json") && Contains("rate_in_dps"));
  auto s = fogctl(d, "simulate --help");
  CHECK(s.code == 0);
  CHECK_THAT(s.out, Contains("--rate-sequence") && Contains("--sf-tc") && Contains("ppm/degC"));
}

TEST_CASE("fogctl simulate --rate-sequence writes the rate CSV that fogctl scale-factor fits", "[scale_factor][process]") {
  Dir d("sfp");
  const auto profile = d.write("p.profile", "setpoint 20 C\nhold 10 min\nramp to 40 C at 1 C/min\nhold 20 min\n");
  auto s = fogctl(d, "simulate --profile '" + profile + "' --rate-sequence '0,50,-50,200,-200' --rate-step 20 --sf-tc 10 -q -o '" +
                         d.file("run.csv") + "'");
  INFO(s.err);
  REQUIRE(s.code == 0);
  CHECK_THAT(slurp(d.file("run.csv")), Contains("rate_in_dps,rate_out_dps"));
  auto r = fogctl(d, "scale-factor '" + d.file("run.csv") + "' --json");
  INFO(r.err);
  REQUIRE(r.code == 0);
  const auto j = nlohmann::json::parse(r.out);
  CHECK(j["plateaus"].size() == 3);
  CHECK(j["tc_ppm_per_c"]["value"].get<double>() == Approx(10.0).margin(1.0));
}

TEST_CASE("fogctl scale-factor exits 2 naming the line and column of a bad cell, and --sf-tc needs --rate-sequence", "[scale_factor][process]") {
  Dir d("sfp");
  const auto bad = d.write("bad.csv", "time_s,plateau,rate_in_dps,rate_out_dps,t1_c\n0,1,0,0,20\n1,1,10,zz,20\n");
  auto r = fogctl(d, "scale-factor '" + bad + "'");
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Contains("bad.csv:3: column 4 'rate_out_dps': not a number: 'zz'"));
  auto s = fogctl(d, "simulate --profile exp1 --sf-tc 5 -q");
  CHECK(s.code == 2);
  CHECK_THAT(s.err, Contains("--rate-sequence"));
}
