// The live panel as an operator's screen (issue 28; docs/web.md, "The operator's screen") in
// headless Chromium against a live daemon on the mock bench (paced at time scale 100): a plan of
// a fit and a verify step for two units (SIM-0002 with a sensitivity the model lacks fails the
// plan's comp_raw limit) and a plan in the queue. Checked at a line PC's 1280x800 and a tablet's
// 800x1280: a large verdict per slot and serial (IN TEST, then PASS and FAIL), the wall-clock
// time, the queue's next plan and its units, no horizontal scrolling, the print view (no form,
// no section or plot cut), and the runs' table after a reload during a run (each run once,
// newest first). Screenshots and the printed PDF go to the artefacts directory,
// <build>/test-artefacts/web-operator-panel/. Without Chromium: SKIPPED (exit 77).
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

const char* kPlan =
    "plan fit-verify\n"
    "step pfit fit\n"
    "step pver verify\n"
    "limit comp_raw < 0.2 stop\n";

std::string q(const std::string& js) { return "(() => { try { return " + js + "; } catch (e) { return null; } })()"; }

std::string tile(const std::string& slot, const std::string& serial) {
  return "document.querySelector('#board-units .tile[data-slot=\"" + slot + "\"][data-serial=\"" + serial + "\"]')";
}

// The page's width: nothing wider than the window (no horizontal scrolling).
const std::string kNoOverflow = "document.scrollingElement.scrollWidth <= window.innerWidth";
// Every plot's canvas inside the window.
const std::string kPlotsInside =
    "Array.from(document.querySelectorAll('.plot canvas')).every(c => c.getBoundingClientRect().right <= window.innerWidth + 0.5)";
// A tile readable from across the room: its verdict at least 48 px high, the tile on the first screen.
std::string large_on_screen(const std::string& t) {
  return q("parseFloat(getComputedStyle(" + t + ".querySelector('.big')).fontSize) >= 48 && " + t +
           ".getBoundingClientRect().bottom <= window.innerHeight && " + t + ".getBoundingClientRect().right <= window.innerWidth");
}

void viewport(Browser& b, int width, int height) {
  REQUIRE(b.cdp("Emulation.setDeviceMetricsOverride",
                {{"width", width}, {"height", height}, {"deviceScaleFactor", 1}, {"mobile", false}})
              .is_object());
  std::this_thread::sleep_for(1s);  // the plots follow the width after 150 ms
}

std::filesystem::path artefacts() {
  auto dir = std::filesystem::path(FOGBENCH_BIN_DIR).parent_path() / "test-artefacts" / "web-operator-panel";
  std::filesystem::create_directories(dir);
  return dir;
}

void keep(const std::filesystem::path& file, const std::string& bytes) {
  std::ofstream(file, std::ios::binary) << bytes;
  std::cout << "artefact: " << file.string() << " (" << bytes.size() << " bytes)" << std::endl;
}

// The runs' table as run ids, top to bottom.
const std::string kRunIds =
    "Array.from(document.querySelectorAll('#verdicts tbody tr')).map(tr => Number(tr.cells[0].textContent))";

void check_history(const json& ids, std::int64_t newest, std::size_t at_least) {
  INFO("runs' table: " << ids.dump());
  REQUIRE(ids.is_array());
  CHECK(ids.size() >= at_least);
  if (!ids.empty()) CHECK(ids[0] == newest);
  for (std::size_t i = 1; i < ids.size(); ++i) CHECK(ids[i - 1].get<std::int64_t>() > ids[i].get<std::int64_t>());
}

}  // namespace

TEST_CASE("the live panel as an operator's screen at 1280x800 and 800x1280, printed, and its history after a reload, in headless Chromium") {
  require_sim();
  const std::string exe = find_chromium();
  if (exe.empty()) {
    std::cout << "SKIPPED: Chromium not found (Debian package: chromium): the panel cannot be tested" << std::endl;
    std::_Exit(77);
  }
  json sim = {{"units", {{{"serial", "SIM-0001"}}, {{"serial", "SIM-0002"}, {"effects", "0.8*T1"}}}}};
  LiveBench bench(100.0, {{"web", {{"listen", "127.0.0.1:0"}}}}, true, sim);
  std::ofstream(bench.dir / "profiles" / "pfit.profile")
      << "setpoint 20 C\nhold 10 min\nramp to 30 C at 1 C/min\nhold 15 min\nramp to 20 C at 1 C/min\nhold 15 min\n";
  std::ofstream(bench.dir / "profiles" / "pver.profile")
      << "setpoint 20 C\nhold 5 min\nramp to 25 C at 1 C/min\nhold 10 min\nramp to 15 C at 1 C/min\nhold 5 min\n"
         "ramp to 20 C at 1 C/min\nhold 2 min\n";
  const auto port = bench.ready_daemon["web_port"].get<std::uint16_t>();
  Browser b(exe, bench.dir, "http://127.0.0.1:" + std::to_string(port) + "/");
  INFO("chromium log in " << (bench.dir / "chrome.log") << ", fogbenchd log in " << (bench.dir / "fogbenchd.log"));
  REQUIRE(b.ok());
  const auto out = artefacts();
  viewport(b, 1280, 800);
  REQUIRE(b.until("document.getElementById('conn').className === 'up'", 60s));

  // The wall-clock time, in the header: the machine's, to the second.
  CHECK(b.until(q("/^\\d{4}-\\d\\d-\\d\\d \\d\\d:\\d\\d:\\d\\d$/.test(document.getElementById('clock').textContent)"), 10s));
  const json clock_ms = b.eval(q("Number(document.getElementById('clock').dataset.epochMs)"));
  const auto now_ms = std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::system_clock::now().time_since_epoch()).count();
  CHECK(clock_ms.is_number());
  if (clock_ms.is_number()) CHECK(std::abs(clock_ms.get<double>() - static_cast<double>(now_ms)) < 5000.0);
  CHECK(b.until(q("document.getElementById('next').textContent === 'Next: nothing queued'"), 30s));

  LineClient c(bench.socket());
  REQUIRE(c.ok());
  auto s = c.call({{"cmd", "plan.start"}, {"text", kPlan}, {"source", "fv.plan"}, {"units", {"SIM-0001", "SIM-0002"}},
                   {"operator", "Ada"}, {"lot", "L-7"}});
  INFO(s.dump());
  REQUIRE(code_of(s) == "ok");
  auto a = c.call({{"cmd", "queue.add"}, {"text", "plan next-one\nstep pfit fit\n"}, {"source", "next.plan"},
                   {"slots", {{"B", "FOG-0099"}}}, {"operator", "Grace"}});
  INFO(a.dump());
  REQUIRE(code_of(a) == "ok");
  const std::string qid = std::to_string(a["result"]["plan_id"].get<std::int64_t>());

  // While the plan runs: each unit IN TEST, large, with its slot and serial; the run's start and
  // expected end in wall-clock time; the queue's next plan with its unit and slot.
  CHECK(b.until(q(tile("A", "SIM-0001") + ".dataset.verdict === 'testing'"), 60s));
  CHECK(b.until(q(tile("B", "SIM-0002") + ".dataset.verdict === 'testing'"), 30s));
  CHECK(b.eval(q(tile("A", "SIM-0001") + ".textContent.includes('IN TEST')")) == true);
  CHECK(b.eval(large_on_screen(tile("A", "SIM-0001"))) == true);
  CHECK(b.until(q("/^\\d\\d:\\d\\d$/.test(document.getElementById('run-started').textContent)"), 30s));
  CHECK(b.until(q("document.getElementById('run-ends').textContent.startsWith('about ') && "
                  "Number(document.getElementById('run-ends').dataset.epochMs) > Date.now()"),
                30s));
  CHECK(b.until(q("document.getElementById('next').dataset.planId === '" + qid + "'"), 30s));
  CHECK(b.eval(q("document.querySelector('#next .next-unit[data-serial=\"FOG-0099\"]').dataset.slot")) == "B");
  CHECK(b.eval(q("document.getElementById('next').textContent.includes('next-one') && "
                 "document.getElementById('next').textContent.includes('Grace')")) == true);
  CHECK(b.until(q(kNoOverflow), 10s));
  keep(out / "panel-1280x800-running.png", b.screenshot());

  // The queued plan taken out: nothing is next.
  REQUIRE(code_of(c.call({{"cmd", "queue.remove"}, {"plan_id", std::stoll(qid)}})) == "ok");
  CHECK(b.until(q("document.getElementById('next').textContent === 'Next: nothing queued'"), 30s));

  // The plan's end: SIM-0001 PASS, SIM-0002 FAIL (dropped at the verify step), large, on the
  // first screen of a 1280x800 line PC, and nothing wider than it.
  const auto deadline = SteadyClock::now() + 400s;
  std::string plan_state;
  while (SteadyClock::now() < deadline && plan_state != "completed") {
    plan_state = c.call({{"cmd", "plan.status"}, {"plan_id", s["result"]["plan_id"]}})["result"].value("state", "");
    std::this_thread::sleep_for(500ms);
  }
  REQUIRE(plan_state == "completed");
  CHECK(b.until(q(tile("B", "SIM-0002") + ".dataset.verdict === 'fail' && " + tile("A", "SIM-0001") + ".dataset.verdict === 'pass'"),
                30s));
  CHECK(b.eval(q(tile("A", "SIM-0001") + ".querySelector('.big').textContent")) == "PASS");
  CHECK(b.eval(q(tile("B", "SIM-0002") + ".querySelector('.big').textContent")) == "FAIL");
  CHECK(b.eval(large_on_screen(tile("A", "SIM-0001"))) == true);
  CHECK(b.eval(large_on_screen(tile("B", "SIM-0002"))) == true);
  CHECK(b.eval(q(kNoOverflow)) == true);
  CHECK(b.eval(q(kPlotsInside)) == true);
  keep(out / "panel-1280x800.png", b.screenshot());

  // A tablet, upright: the same, nothing wider than 800 px.
  viewport(b, 800, 1280);
  CHECK(b.until(q(kNoOverflow), 10s));
  CHECK(b.until(q(kPlotsInside), 10s));
  CHECK(b.eval(large_on_screen(tile("A", "SIM-0001"))) == true);
  CHECK(b.eval(large_on_screen(tile("B", "SIM-0002"))) == true);
  keep(out / "panel-800x1280.png", b.screenshot());

  // Printed (the print media on a page 700 px wide, about A4's printable width): no Start/Abort
  // form, no section split over two pages, every plot inside the page.
  viewport(b, 700, 1000);
  REQUIRE(b.cdp("Emulation.setEmulatedMedia", {{"media", "print"}}).is_object());
  std::this_thread::sleep_for(1s);
  CHECK(b.eval(q("getComputedStyle(document.getElementById('control')).display")) == "none");
  CHECK(b.eval(q("Array.from(document.querySelectorAll('main > section')).every(s => getComputedStyle(s).breakInside === 'avoid')")) == true);
  CHECK(b.until(q(kPlotsInside), 10s));
  CHECK(b.eval(q(kNoOverflow)) == true);
  CHECK(b.eval(q("getComputedStyle(" + tile("A", "SIM-0001") + ").display")) != "none");
  keep(out / "panel-print-700.png", b.screenshot());
  const std::string pdf = b.pdf();
  CHECK(pdf.rfind("%PDF", 0) == 0);
  keep(out / "panel-print.pdf", pdf);
  REQUIRE(b.cdp("Emulation.setEmulatedMedia", {{"media", ""}}).is_object());
  viewport(b, 1280, 800);

  // History: a bare run after the plan's two, the page reloaded during it. The runs' table has
  // each run once, newest first, and so it stays when refreshes overlap.
  const auto run3 = bench.start_run(c, "pfit", {"SIM-0001"});
  CHECK(b.until("document.getElementById('run-id').textContent === '" + std::to_string(run3) + "'", 60s));
  REQUIRE(b.cdp("Page.reload", {{"ignoreCache", true}}).is_object());
  REQUIRE(b.until("document.getElementById('conn') && document.getElementById('conn').className === 'up' && "
                  "document.getElementById('run-id').textContent === '" + std::to_string(run3) + "'",
                  60s));
  CHECK(b.until(q(kRunIds + ".length >= 3"), 30s));
  std::this_thread::sleep_for(3s);  // every refresh the reload started has answered
  check_history(b.eval(q(kRunIds)), run3, 3);
  CHECK(b.until(q(tile("A", "SIM-0001") + ".dataset.verdict === 'testing'"), 30s));
  check_history(b.eval(q("Promise.all([fogPanel.refreshVerdicts(), fogPanel.refreshVerdicts(), fogPanel.refreshVerdicts()]).then(() => " +
                         kRunIds + ")")),
                run3, 3);
  keep(out / "panel-1280x800-reloaded.png", b.screenshot());
  REQUIRE(code_of(c.call({{"cmd", "run.abort"}, {"reason", "panel test done"}})) == "ok");
  bench.wait_state(c, run3, {"aborted"}, 60s);
}

namespace {

// Injected before the page's scripts (Page.addScriptToEvaluateOnNewDocument): the panel's
// WebSocket holds each `run.list` reply until a second one is held (two refreshes of the runs'
// table under way at once) or 1.5 s have passed, then hands the held replies to the page in one
// go, newest request first. Two overlapping refreshes thus always resume together, whatever the
// machine's speed, and the older reply lands last: a page that lists a run twice or keeps a
// stale order when refreshes overlap shows it every time. __fogHold counts what it saw.
const char* kHoldRunList = R"JS(
(() => {
  const Native = window.WebSocket;
  window.__fogHold = { lists: 0, overlapped: 0 };
  window.WebSocket = class extends Native {
    constructor(...args) {
      super(...args);
      const cmds = new Map();
      const nativeSend = this.send.bind(this);
      this.send = (data) => {
        try { const m = JSON.parse(data); cmds.set(m.id, m.cmd); } catch (e) { /* not JSON */ }
        nativeSend(data);
      };
      let handler = null;
      let held = [];
      let timer = null;
      const flush = () => {
        clearTimeout(timer);
        timer = null;
        const batch = held.reverse();
        held = [];
        for (const ev of batch) if (handler) handler.call(this, ev);
      };
      Object.defineProperty(this, "onmessage", { get: () => handler, set: (h) => { handler = h; } });
      this.addEventListener("message", (ev) => {
        let m = null;
        try { m = JSON.parse(ev.data); } catch (e) { /* not JSON */ }
        if (m && m.type === "reply" && cmds.get(m.id) === "run.list") {
          window.__fogHold.lists++;
          held.push(ev);
          if (held.length >= 2) { window.__fogHold.overlapped++; flush(); }
          else timer = setTimeout(flush, 1500);
          return;
        }
        if (handler) handler.call(this, ev);
      });
    }
  };
})();
)JS";

}  // namespace

TEST_CASE("the live panel's runs' table after a reload during a run, its refreshes made to overlap: each run once, newest first") {
  require_sim();
  const std::string exe = find_chromium();
  if (exe.empty()) {
    std::cout << "SKIPPED: Chromium not found (Debian package: chromium): the panel cannot be tested" << std::endl;
    std::_Exit(77);
  }
  LiveBench bench(100.0, {{"web", {{"listen", "127.0.0.1:0"}}}});
  std::ofstream(bench.dir / "profiles" / "quick.profile") << "setpoint 20 C\nhold 5 min\n";
  std::ofstream(bench.dir / "profiles" / "long.profile") << "setpoint 20 C\nhold 300 min\n";
  LineClient c(bench.socket());
  REQUIRE(c.ok());
  // Two completed runs (the page asks run.get for each, so a refresh awaits in the middle of its
  // rows), then a third running while the page is reloaded.
  std::vector<std::int64_t> done;
  for (int i = 0; i < 2; ++i) {
    const auto id = bench.start_run(c, "quick", {"SIM-0001"});
    const auto r = bench.wait_state(c, id, {"completed", "failed", "aborted"}, 120s);
    INFO(r.dump());
    REQUIRE(r["result"]["run"]["state"] == "completed");
    done.push_back(id);
  }
  const auto run3 = bench.start_run(c, "long", {"SIM-0001"});
  const auto port = bench.ready_daemon["web_port"].get<std::uint16_t>();
  Browser b(exe, bench.dir, "http://127.0.0.1:" + std::to_string(port) + "/");
  INFO("chromium log in " << (bench.dir / "chrome.log") << ", fogbenchd log in " << (bench.dir / "fogbenchd.log"));
  REQUIRE(b.ok());
  REQUIRE(b.until("document.getElementById('conn').className === 'up'", 60s));
  CHECK(b.until("document.getElementById('run-id').textContent === '" + std::to_string(run3) + "'", 60s));

  // The reload, with every run.list reply held as above.
  REQUIRE(b.cdp("Page.enable").is_object());  // the script is added to the documents the page loads from now on
  REQUIRE(b.cdp("Page.addScriptToEvaluateOnNewDocument", {{"source", kHoldRunList}}).is_object());
  REQUIRE(b.cdp("Page.reload", {{"ignoreCache", true}}).is_object());
  const bool reloaded = b.until("window.__fogHold !== undefined && document.getElementById('conn').className === 'up' && "
                                "document.getElementById('run-id').textContent === '" + std::to_string(run3) + "'",
                                60s);
  INFO("after the reload: " << b.eval(q("JSON.stringify({hold: window.__fogHold, conn: document.getElementById('conn').className, "
                                        "run: document.getElementById('run-id').textContent})")).dump());
  REQUIRE(reloaded);
  // The page's own two refreshes at the reconnect (the status's new run, then the connection's),
  // held and handed over together; the table read once both have answered.
  CHECK(b.until(q("window.__fogHold.lists >= 2"), 30s));
  std::this_thread::sleep_for(3s);
  INFO("held run.list replies: " << b.eval(q("JSON.stringify(window.__fogHold)")).dump());
  const json reloaded_ids = b.eval(q(kRunIds));
  check_history(reloaded_ids, run3, 3);
  if (reloaded_ids.is_array() && reloaded_ids.size() >= 3) {
    CHECK(reloaded_ids[1] == done[1]);
    CHECK(reloaded_ids[2] == done[0]);
  }
  // Two more at once from the test, read as soon as both have answered (a third, alone, would
  // redraw the table whole and hide what the pair did).
  check_history(b.eval(q("Promise.all([fogPanel.refreshVerdicts(), fogPanel.refreshVerdicts()]).then(() => " + kRunIds + ")")),
                run3, 3);
  // Read again after the page's timers had their turn: still each run once, newest first.
  std::this_thread::sleep_for(3s);
  check_history(b.eval(q(kRunIds)), run3, 3);
  CHECK(b.eval(q("window.__fogHold.lists >= 2")) == true);
  REQUIRE(code_of(c.call({{"cmd", "run.abort"}, {"reason", "panel test done"}})) == "ok");
  bench.wait_state(c, run3, {"aborted"}, 60s);
}
