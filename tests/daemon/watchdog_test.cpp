// systemd's watchdog fed from the event loop (daemon/src/watchdog.hpp, issue 27 point 2): WATCHDOG=1
// only while the loop runs what is posted to it. The rounds are driven by hand on a fake loop (a
// queue the test runs or not): no thread, no clock.
#include <catch2/catch.hpp>
#include <functional>
#include <vector>

#include "../../daemon/src/watchdog.hpp"

using fogbench::daemon::LoopWatchdogRounds;

namespace {

// A loop that queues what is posted and runs it only when told.
struct HeldLoop {
  std::vector<std::function<void()>> queued;
  void run_all() {
    auto tasks = std::move(queued);
    queued.clear();
    for (auto& t : tasks) t();
  }
};

}  // namespace

TEST_CASE("watchdog: a loop that runs its tasks is pinged every round, a stuck one once at most, then again when it turns") {
  HeldLoop loop;
  int pings = 0;
  LoopWatchdogRounds w([&](std::function<void()> t) { loop.queued.push_back(std::move(t)); }, [&] { ++pings; });

  // A healthy loop: each round's task has run by the next round.
  for (int i = 0; i < 5; ++i) {
    w.round();
    loop.run_all();
  }
  CHECK(pings == 5);

  // Stuck (a handler that does not return): the task of the last healthy round ran, so one more
  // ping; then none, however many rounds pass (systemd's WatchdogSec= restarts the daemon).
  w.round();
  CHECK(pings == 6);
  for (int i = 0; i < 20; ++i) w.round();
  CHECK(pings == 6);
  CHECK(loop.queued.size() == 21);  // posted all the same: the first one run revives the pings

  // The loop turns again: the pings come back at the next round.
  loop.run_all();
  w.round();
  CHECK(pings == 7);
}

TEST_CASE("watchdog: a task run after the rounds are gone is harmless") {
  HeldLoop loop;
  int pings = 0;
  {
    LoopWatchdogRounds w([&](std::function<void()> t) { loop.queued.push_back(std::move(t)); }, [&] { ++pings; });
    w.round();
  }
  REQUIRE(loop.queued.size() == 1);
  loop.run_all();  // the loop drains after the watchdog went (fogbenchd's stop)
  CHECK(pings == 1);
}
