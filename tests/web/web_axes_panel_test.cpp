// A three-axis unit on the live panel (issue 29 point 3; docs/web.md "Three-axis units") in
// headless Chromium against a live daemon on the mock bench (fogbench-sim --axes 3, y drifting
// with T1 alone: --axis-effect y=0.5*T1): a plan of a fit and a verify step whose comp_raw limit
// y misses. The board's tile shows the unit's FAIL with each axis' verdict beside it (x PASS,
// y FAIL, z PASS), the runs' table each axis after the unit's verdict, and the plan's view each
// measurement with its axis. Without Chromium: SKIPPED (exit 77).
#include <catch2/catch.hpp>

#include <cstdlib>
#include <iostream>

#include "../daemon/live_bench.hpp"
#include "browser.hpp"
#include "web_client.hpp"

using namespace fogbench::daemon::test;
using namespace fogbench::daemon::test::live;
using namespace fogbench::web_test;
using nlohmann::json;

namespace {

const char* kAxesPanelPlan =
    "plan axes\n"
    "step afit fit\n"
    "step aver verify\n"
    "limit comp_raw < 0.2 stop\n";

std::string axes_q(const std::string& js) { return "(() => { try { return " + js + "; } catch (e) { return null; } })()"; }

}  // namespace

TEST_CASE("the live panel shows a three-axis unit's axes beside its verdict: the tile, the runs' table and the plan, in headless Chromium") {
  require_sim();
  const std::string exe = find_chromium();
  if (exe.empty()) {
    std::cout << "SKIPPED: Chromium not found (Debian package: chromium): the panel cannot be tested" << std::endl;
    std::_Exit(77);
  }
  LiveBench bench(100.0, {{"web", {{"listen", "127.0.0.1:0"}}}}, true, nullptr, {"--axes", "3", "--axis-effect", "y=0.5*T1"});
  std::ofstream(bench.dir / "profiles" / "afit.profile")
      << "setpoint 20 C\nhold 10 min\nramp to 30 C at 1 C/min\nhold 15 min\nramp to 20 C at 1 C/min\nhold 15 min\n";
  std::ofstream(bench.dir / "profiles" / "aver.profile")
      << "setpoint 20 C\nhold 5 min\nramp to 25 C at 1 C/min\nhold 10 min\nramp to 15 C at 1 C/min\nhold 5 min\n"
         "ramp to 20 C at 1 C/min\nhold 2 min\n";
  const auto port = bench.ready_daemon["web_port"].get<std::uint16_t>();
  Browser b(exe, bench.dir, "http://127.0.0.1:" + std::to_string(port) + "/");
  INFO("chromium log in " << (bench.dir / "chrome.log") << ", fogbenchd log in " << (bench.dir / "fogbenchd.log"));
  REQUIRE(b.ok());
  REQUIRE(b.until("document.getElementById('conn').className === 'up'", 60s));

  LineClient c(bench.socket());
  REQUIRE(c.ok());
  auto s = c.call({{"cmd", "plan.start"}, {"text", kAxesPanelPlan}, {"source", "axes.plan"}, {"units", {"SIM-0001"}}});
  INFO(s.dump());
  REQUIRE(code_of(s) == "ok");
  const auto deadline = SteadyClock::now() + 400s;
  json st;
  while (SteadyClock::now() < deadline) {
    st = c.call({{"cmd", "plan.status"}, {"plan_id", s["result"]["plan_id"]}});
    if (st["result"].value("state", "") == "completed") break;
    std::this_thread::sleep_for(500ms);
  }
  INFO(st.dump());
  REQUIRE(st["result"]["state"] == "completed");
  REQUIRE(st["result"]["progress"]["units"][0]["verdict"] == "fail");

  // The tile: the unit's FAIL, large, and under it each axis' own verdict.
  const std::string tile = "document.querySelector('#board-units .tile[data-serial=\"SIM-0001\"]')";
  CHECK(b.until(axes_q(tile + ".dataset.verdict === 'fail'"), 30s));
  CHECK(b.until(axes_q(tile + ".querySelectorAll('.axes .axis').length === 3"), 30s));
  for (const auto& [axis, verdict] : std::vector<std::pair<std::string, std::string>>{{"x", "pass"}, {"y", "fail"}, {"z", "pass"}}) {
    INFO("axis " << axis);
    CHECK(b.eval(axes_q(tile + ".querySelector('.axes .axis[data-axis=\"" + axis + "\"]').dataset.verdict")) == verdict);
  }
  CHECK(b.eval(axes_q(tile + ".querySelector('.axes').textContent")) == "x PASSy FAILz PASS");
  // The runs' table: the verify run's unit FAIL, then its axes.
  CHECK(b.until(axes_q("document.querySelector('#verdicts .axes-line[data-serial=\"SIM-0001\"] .axis[data-axis=\"y\"]').dataset.verdict === 'fail'"),
                30s));
  CHECK(b.eval(axes_q("document.querySelector('#verdicts .axes-line[data-serial=\"SIM-0001\"] .axis[data-axis=\"x\"]').dataset.verdict")) ==
        "pass");
  // The plan's view: the verify step's measurements, each named with its axis, y's not met.
  CHECK(b.until(axes_q("document.querySelectorAll('#plan span[data-axis]').length >= 3"), 30s));
  CHECK(b.eval(axes_q("Array.from(document.querySelectorAll('#plan span[data-axis=\"y\"]')).some(s => s.textContent.startsWith('comp_raw (y) ') && s.className === 'fail')")) ==
        true);
}
