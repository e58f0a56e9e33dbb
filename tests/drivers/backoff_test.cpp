// The reconnection backoff policy, walked with injected time.
#include <catch2/catch.hpp>

#include "fogbench/drivers/backoff.hpp"

using namespace fogbench::drivers;
using namespace std::chrono_literals;

TEST_CASE("backoff doubles from the initial delay up to the cap, and resets on success") {
  Backoff b({250, 30000, 2.0});
  const Backoff::TimePoint t0{};
  CHECK(b.may_attempt(t0));  // nothing failed yet
  // 250 * 2^(n-1), capped at 30000: 250, 500, 1000, 2000, 4000, 8000, 16000, 30000, 30000.
  const std::int64_t expected[] = {250, 500, 1000, 2000, 4000, 8000, 16000, 30000, 30000};
  for (std::int64_t ms : expected) CHECK(b.record_failure(t0).count() == ms);
  CHECK(b.consecutive_failures() == 9);
  b.record_success();
  CHECK(b.consecutive_failures() == 0);
  CHECK(b.record_failure(t0).count() == 250);
}

TEST_CASE("no attempt before the delay has passed") {
  Backoff b({100, 1000, 3.0});
  const Backoff::TimePoint t0{};
  CHECK(b.record_failure(t0) == 100ms);
  CHECK_FALSE(b.may_attempt(t0 + 99ms));
  CHECK(b.remaining(t0 + 40ms) == 60ms);
  CHECK(b.may_attempt(t0 + 100ms));
  CHECK(b.remaining(t0 + 100ms) == 0ms);
  // Second failure at t0 + 100 ms: 100 * 3 = 300 ms from then.
  CHECK(b.record_failure(t0 + 100ms) == 300ms);
  CHECK_FALSE(b.may_attempt(t0 + 399ms));
  CHECK(b.may_attempt(t0 + 400ms));
  // Third: 900 ms; fourth: 2700 capped to 1000 ms.
  CHECK(b.record_failure(t0 + 400ms) == 900ms);
  CHECK(b.record_failure(t0 + 1300ms) == 1000ms);
}

TEST_CASE("a long outage does not overflow the delay") {
  Backoff b({250, 60000, 10.0});
  Backoff::TimePoint t{};
  for (int i = 0; i < 5000; ++i) t += b.record_failure(t);
  CHECK(b.record_failure(t).count() == 60000);
}
