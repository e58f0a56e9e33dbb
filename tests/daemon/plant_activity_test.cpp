// The plant link's state as `status.plant` shows it (daemon/src/plant_activity.hpp): idle and
// stopped are never stalled; a connection attempt or a run's transaction is stalled once it has
// gone stall_s without progress, however long it has run before, and progress clears it.
#include <catch2/catch.hpp>

#include "../../daemon/src/plant_activity.hpp"

using namespace fogbench::daemon;

TEST_CASE("plant activity: a transaction without progress for stall_s is stalled, progress clears it") {
  PlantActivity a;
  a.phase = PlantActivity::Phase::sending;
  a.run_id = 7;
  a.began_s = 100;
  a.progress_s = 100;
  // 9.9 s without progress, threshold 10 s: sending, not stalled.
  auto s = describe(a, 109.9, 10);
  CHECK(s.state == "sending");
  CHECK_FALSE(s.stalled);
  CHECK(s.run_id == 7);
  CHECK(s.busy_s == Approx(9.9));
  CHECK(s.quiet_s == Approx(9.9));
  // At the threshold: stalled.
  s = describe(a, 110, 10);
  CHECK(s.state == "stalled");
  CHECK(s.stalled);
  CHECK(s.run_id == 7);
  // A long transaction that keeps progressing (a big COPY) is not stalled: progress 2 s ago.
  a.progress_s = 498;
  s = describe(a, 500, 10);
  CHECK(s.state == "sending");
  CHECK_FALSE(s.stalled);
  CHECK(s.busy_s == Approx(400));
  CHECK(s.quiet_s == Approx(2));
}

TEST_CASE("plant activity: idle and stopped are never stalled, a hanging connection attempt is") {
  PlantActivity a;
  a.began_s = a.progress_s = 0;
  auto s = describe(a, 1e6, 10);
  CHECK(s.state == "idle");
  CHECK_FALSE(s.stalled);
  CHECK(s.quiet_s == 0);
  a.phase = PlantActivity::Phase::stopped;
  CHECK(describe(a, 1e6, 10).state == "stopped");
  CHECK_FALSE(describe(a, 1e6, 10).stalled);
  a.phase = PlantActivity::Phase::connecting;
  s = describe(a, 30, 10);
  CHECK(s.state == "stalled");
  CHECK(s.run_id == 0);
  // A clock read on another thread before the phase was noted: no negative durations.
  a.began_s = a.progress_s = 50;
  s = describe(a, 49.5, 10);
  CHECK(s.state == "connecting");
  CHECK(s.busy_s == 0);
  CHECK(s.quiet_s == 0);
}
