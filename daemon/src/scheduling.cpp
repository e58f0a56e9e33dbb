// The loop thread's scheduler slice (scheduling.hpp): sched_setattr / sched_getattr, which glibc
// does not wrap, called through syscall(2).
#include "fogbench/daemon/scheduling.hpp"

#include <sched.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <sstream>

namespace fogbench::daemon {

namespace {

// struct sched_attr as the kernel defines it (linux/sched/types.h, SCHED_ATTR_SIZE_VER1); spelled
// out so this file does not depend on the installed kernel headers' version.
struct SchedAttr {
  std::uint32_t size = sizeof(SchedAttr);
  std::uint32_t sched_policy = 0;
  std::uint64_t sched_flags = 0;
  std::int32_t sched_nice = 0;
  std::uint32_t sched_priority = 0;
  std::uint64_t sched_runtime = 0;  // for SCHED_OTHER / SCHED_BATCH on 6.12+: the slice, ns
  std::uint64_t sched_deadline = 0;
  std::uint64_t sched_period = 0;
  std::uint32_t sched_util_min = 0;
  std::uint32_t sched_util_max = 0;
};
static_assert(sizeof(SchedAttr) == 56, "SCHED_ATTR_SIZE_VER1");

int get_attr(SchedAttr& a) {
  a = SchedAttr{};
  return static_cast<int>(::syscall(SYS_sched_getattr, 0, &a, static_cast<unsigned>(sizeof a), 0U));
}

std::string ms(std::uint64_t ns) {
  std::ostringstream o;
  o << static_cast<double>(ns) / 1e6 << " ms";
  return o.str();
}

}  // namespace

std::uint64_t current_scheduler_slice_ns() {
  SchedAttr a;
  if (get_attr(a) != 0) return 0;
  if (a.sched_policy != SCHED_OTHER && a.sched_policy != SCHED_BATCH) return 0;
  return a.sched_runtime;
}

SliceRequest request_scheduler_slice(std::chrono::nanoseconds slice) {
  SliceRequest r;
  SchedAttr a;
  if (get_attr(a) != 0) {
    r.message = std::string("sched_getattr: ") + std::strerror(errno) + "; the kernel's default slice is kept";
    return r;
  }
  if (a.sched_policy != SCHED_OTHER && a.sched_policy != SCHED_BATCH) {
    r.message = "not a SCHED_OTHER thread (policy " + std::to_string(a.sched_policy) + "): its scheduling is left alone";
    return r;
  }
  // The kernel's own clamp (0.1..100 ms), so the read-back can be compared.
  const auto asked = static_cast<std::uint64_t>(std::max<std::int64_t>(slice.count(), 0));
  const std::uint64_t want = std::min<std::uint64_t>(std::max<std::uint64_t>(asked, 100'000), 100'000'000);
  a.size = sizeof a;
  a.sched_flags = 0;
  a.sched_runtime = want;
  a.sched_deadline = 0;
  a.sched_period = 0;
  if (::syscall(SYS_sched_setattr, 0, &a, 0U) != 0) {
    r.message = std::string("sched_setattr: ") + std::strerror(errno) + "; the kernel's default slice is kept";
    return r;
  }
  r.slice_ns = current_scheduler_slice_ns();
  r.applied = r.slice_ns == want;
  if (r.applied)
    r.message = "a " + ms(want) + " scheduler slice: its wake-ups preempt tasks with longer slices (EEVDF)";
  else
    r.message = "the kernel keeps its default slice (custom slices need Linux 6.12 or later): a wake-up may wait "
                "behind a busy task's slice, a few ms";
  return r;
}

}  // namespace fogbench::daemon
