// The live panel in headless Chromium against a live daemon on the mock bench, driven over
// Chromium's DevTools protocol (a WebSocket, from the Beast client of web_client.hpp): the page
// loads, its plots receive samples (the page counts them in the DOM), a fault injected in the
// simulator shows in the events list, abort without the token is refused and with it taken, and
// the page reconnects by itself when the daemon restarts. Without Chromium the test reports
// SKIPPED (exit 77, SKIP_RETURN_CODE of test_web), never passes.
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
const std::string kToken = "web-panel-token-0123456789";
}  // namespace

TEST_CASE("the live panel in headless Chromium: samples plotted, a fault shown, abort needs the token, reconnects") {
  require_sim();
  const std::string exe = find_chromium();
  if (exe.empty()) {
    std::cout << "SKIPPED: Chromium not found (Debian package: chromium): the panel cannot be tested" << std::endl;
    std::_Exit(77);
  }
  const auto web_port = free_port();
  LiveBench bench(20.0,
                  {{"web", {{"listen", "127.0.0.1:" + std::to_string(web_port)}}},
                   {"socket", {{"tcp", {{"port", free_port()}, {"token", kToken}}}}}},
                  true);
  REQUIRE(bench.ready_daemon["web_port"] == web_port);
  Browser b(exe, bench.dir, "http://127.0.0.1:" + std::to_string(web_port) + "/");
  INFO("chromium log in " << (bench.dir / "chrome.log") << ", fogbenchd log in " << (bench.dir / "fogbenchd.log"));
  REQUIRE(b.ok());

  // The page loads, uPlot with it, and connects.
  REQUIRE(b.until("document.getElementById('conn').className === 'up'", 60s));
  CHECK(b.eval("typeof uPlot") == "function");
  CHECK(b.until("document.querySelectorAll('#profile option').length > 0", 30s));
  CHECK(b.eval("Array.from(document.querySelectorAll('#profile option')).some(o => o.value === 'short')") == true);

  // A run: its samples reach the page and its plots.
  LineClient c(bench.socket());
  REQUIRE(c.ok());
  const auto run = bench.start_run(c, "short", {"SIM-0001", "SIM-0002"});
  REQUIRE(b.until("Number(document.getElementById('samples').dataset.count) >= 20", 120s));
  CHECK(b.until("Number(document.getElementById('plot-drift').dataset.points) >= 5", 30s));
  CHECK(b.eval("document.querySelectorAll('#plot-drift canvas').length") == 1);
  CHECK(b.until("document.getElementById('run-id').textContent === '" + std::to_string(run) + "'", 30s));
  CHECK(b.eval("document.getElementById('run-elapsed').textContent.length > 0") == true);
  // A picture for people (only if FOGBENCH_PANEL_SHOT names a file to write it to).
  if (const char* shot = std::getenv("FOGBENCH_PANEL_SHOT")) {
    std::this_thread::sleep_for(2s);
    std::ofstream(shot, std::ios::binary) << b.screenshot();
  }

  // Abort from the page without the token: refused (forbidden), shown, and the run goes on.
  CHECK(b.eval("fogPanel.abort().then(r => r.error ? r.error.code : 'ok')") == "forbidden");
  CHECK(b.eval("document.getElementById('control-result').dataset.code") == "forbidden");
  CHECK(c.call({{"cmd", "status"}})["result"]["run"]["id"] == run);

  // A fault in the simulator: the chamber's alarm. It shows in the events list as it happens.
  REQUIRE(bench.sim_command({{"cmd", "fault"}, {"name", "alarm"}, {"on", true}})["ok"] == true);
  CHECK(b.until("Array.from(document.querySelectorAll('#events li.alarm')).length > 0", 120s));
  CHECK(b.until("document.querySelector('#verdicts tbody') && document.querySelector('#verdicts tbody').textContent.includes('aborted')", 60s));
  REQUIRE(bench.sim_command({{"cmd", "fault"}, {"name", "alarm"}, {"on", false}})["ok"] == true);

  // With the token typed in, the page's control goes through (a second run, aborted from the page).
  const auto run2 = bench.start_run(c, "short", {"SIM-0001"});
  CHECK(b.until("document.getElementById('run-id').textContent === '" + std::to_string(run2) + "'", 60s));
  CHECK(b.eval("document.getElementById('token').value = '" + kToken + "'; fogPanel.abort().then(r => r.error ? r.error.code : 'ok')") == "ok");
  CHECK(bench.wait_state(c, run2, {"aborted"}, 60s)["result"]["run"]["reason"] == "aborted by operator: from the web panel");

  // The Start form: a serial entry per bench slot, prefilled with its default; a barcode
  // scanner's Enter moves on (from the last slot to Start) and starts nothing by itself.
  CHECK(b.eval("document.querySelectorAll('input.slot-serial').length") == 2);
  CHECK(b.eval("document.querySelector('input.slot-serial[data-slot=\"A\"]').value") == "SIM-0001");
  CHECK(b.eval("(() => { const a = document.querySelector('input.slot-serial[data-slot=\"A\"]'); "
               "const s = document.querySelector('input.slot-serial[data-slot=\"B\"]'); "
               "a.focus(); a.value = ''; a.dispatchEvent(new KeyboardEvent('keydown', {key: 'Enter', bubbles: true})); "
               "const moved = document.activeElement === s; s.value = 'FOG-0077'; "
               "s.dispatchEvent(new KeyboardEvent('keydown', {key: 'Enter', bubbles: true})); "
               "return moved && document.activeElement.id === 'start'; })()") == true);
  CHECK(c.call({{"cmd", "status"}})["result"]["run"].is_null());
  const json started = b.eval("document.getElementById('profile').value = 'short'; "
                              "fogPanel.start().then(r => r.error ? r.error.code : r.result.run_id)");
  REQUIRE(started.is_number_integer());
  const json run3 = c.call({{"cmd", "run.get"}, {"run_id", started}})["result"]["run"];
  CHECK(run3["units"] == json{"FOG-0077"});  // slot A left empty: not in the run
  CHECK(run3["slots"] == json{"B"});
  REQUIRE(c.call({{"cmd", "run.abort"}, {"reason", "slots checked"}}).contains("result"));
  bench.wait_state(c, started.get<std::int64_t>(), {"aborted"}, 60s);

  // The daemon restarts: the page notices, and reconnects by itself.
  bench.daemon.reset();
  CHECK(b.until("document.getElementById('conn').className === 'down'", 60s));
  bench.start_daemon();
  CHECK(b.until("document.getElementById('conn').className === 'up' && Number(document.getElementById('conn').dataset.connects) >= 2", 60s));
  // And it reads again: the status of the new daemon (no run).
  CHECK(b.until("document.getElementById('run-id').textContent === 'none'", 30s));
}
