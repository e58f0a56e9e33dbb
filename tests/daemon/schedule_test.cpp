// The acquisition schedule's timing decisions (daemon/src/schedule.hpp) on a fake clock: every
// "now" is t0 plus an offset chosen by the test, so nothing here waits or measures a duration.
#include <catch2/catch.hpp>

#include "../../daemon/src/schedule.hpp"

using namespace fogbench::daemon;
using std::chrono::milliseconds;

namespace {
// Time scale 2: a period of 500 ms, half a period 250 ms.
Schedule at_scale_2() { return Schedule{Schedule::Clock::time_point{} + std::chrono::seconds(100), milliseconds(250)}; }
}  // namespace

TEST_CASE("schedule: ticks at t0 + k periods, the real clock's polls half a period before", "[schedule]") {
  const auto s = at_scale_2();
  CHECK(s.period() == milliseconds(500));
  CHECK(s.tick_due(0) == s.t0);
  CHECK(s.tick_due(3) == s.t0 + milliseconds(1500));
  CHECK(s.slot_due(2 * 3) == s.tick_due(3));
  CHECK(s.slot_due(2 * 3 - 1) == s.tick_due(3) - milliseconds(250));
  CHECK(s.slot_due(-1) == s.t0 - milliseconds(250));
}

TEST_CASE("schedule: the real clock goes on at its slot up to 20 half-periods late, then skips an even number", "[schedule]") {
  const auto s = at_scale_2();
  CHECK(s.real_resume_slot(4, s.slot_due(4)) == 4);
  CHECK(s.real_resume_slot(4, s.slot_due(4) + milliseconds(20 * 250 + 249)) == 4);  // 20 behind
  CHECK(s.real_resume_slot(4, s.slot_due(4) + milliseconds(21 * 250)) == 4 + 20);   // 21: even, a tick stays a tick
  CHECK(s.real_resume_slot(5, s.slot_due(5) + milliseconds(30 * 250 + 1)) == 5 + 30);  // a poll stays a poll
  CHECK(s.real_resume_slot(-1, s.slot_due(-1) + milliseconds(5)) == -1);
}

TEST_CASE("schedule: the paced clock moves t0 forward only when more than two periods late", "[schedule]") {
  const auto s = at_scale_2();
  CHECK(s.paced_shift(7, s.tick_due(7) - milliseconds(100)) == milliseconds(0));  // early
  CHECK(s.paced_shift(7, s.tick_due(7) + milliseconds(1000)) == milliseconds(0));  // exactly two periods
  CHECK(s.paced_shift(7, s.tick_due(7) + milliseconds(1001)) == milliseconds(1001));
  auto moved = s;
  moved.t0 += moved.paced_shift(7, s.tick_due(7) + milliseconds(3000));
  CHECK(moved.tick_due(7) == s.tick_due(7) + milliseconds(3000));  // tick 7 is due now: no burst
}
