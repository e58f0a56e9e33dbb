// The loop thread's scheduler slice (scheduling.hpp): asked of the real kernel on a thread of
// the test's own. On Linux 6.12 and later (EEVDF's custom slices) the kernel must report the
// slice asked for, clamped to 0.1..100 ms; on an older kernel the request must say it was not
// applied, and why. Which of the two is expected comes from uname, not from the call's result.
#include <sys/utsname.h>

#include <catch2/catch.hpp>

#include <cstdio>
#include <thread>

#include "fogbench/daemon/scheduling.hpp"

using namespace fogbench::daemon;

namespace {

bool kernel_has_custom_slices() {
  ::utsname u{};
  REQUIRE(::uname(&u) == 0);
  int major = 0, minor = 0;
  REQUIRE(std::sscanf(u.release, "%d.%d", &major, &minor) == 2);
  return major > 6 || (major == 6 && minor >= 12);
}

// Runs f on a new thread (the slice is per thread: the test runner's own is left as it was).
template <class F>
void on_thread(F f) {
  std::thread t(f);
  t.join();
}

}  // namespace

TEST_CASE("scheduling: the loop's slice is what the kernel reports, clamped to 0.1..100 ms") {
  const bool eevdf = kernel_has_custom_slices();
  on_thread([eevdf] {
    const auto r = request_scheduler_slice(std::chrono::microseconds(100));
    if (eevdf) {
      CHECK(r.applied);
      CHECK(r.slice_ns == 100'000);
      CHECK(current_scheduler_slice_ns() == 100'000);
      CHECK_THAT(r.message, Catch::Contains("0.1 ms"));
      // Below the kernel's minimum: its clamp, 0.1 ms; above: as asked.
      CHECK(request_scheduler_slice(std::chrono::microseconds(10)).slice_ns == 100'000);
      const auto two = request_scheduler_slice(std::chrono::milliseconds(2));
      CHECK(two.applied);
      CHECK(two.slice_ns == 2'000'000);
    } else {
      CHECK_FALSE(r.applied);
      CHECK_THAT(r.message, Catch::Contains("6.12"));
    }
  });
}

TEST_CASE("scheduling: a thread's slice is its own, the other threads keep theirs") {
  const bool eevdf = kernel_has_custom_slices();
  const std::uint64_t mine = current_scheduler_slice_ns();
  // Before 6.12 the kernel reports no slice for a SCHED_OTHER thread at all.
  if (!eevdf) CHECK(mine == 0);
  on_thread([eevdf] { CHECK(request_scheduler_slice(std::chrono::microseconds(300)).applied == eevdf); });
  CHECK(current_scheduler_slice_ns() == mine);
  if (eevdf) CHECK(mine != 300'000);
}

