// The acquisition loop's place on the CPU (issue 14: the tick unaffected while the CPUs are busy
// with the plant's replication or anything else). Linux's EEVDF scheduler (6.6+) lets a task ask
// for a short slice (sched_attr::sched_runtime, 6.12+): a task with a shorter slice than the one
// running preempts it on wake-up, instead of waiting out the running task's slice (measured here:
// the loop woken by its timer waited up to 5 ms behind a PostgreSQL backend copying rows). The
// loop runs about 0.05 ms per wake-up (95th percentile), so the shortest slice the kernel allows,
// 0.1 ms, is its natural one. No privilege is needed (the nice value is not changed); an older
// kernel accepts the call and keeps its default slice, which is then said in the log.
#pragma once

#include <chrono>
#include <cstdint>
#include <string>

namespace fogbench::daemon {

struct SliceRequest {
  bool applied = false;         // the kernel reports the slice asked for (clamped to 0.1..100 ms)
  std::uint64_t slice_ns = 0;   // the slice the kernel reports for the thread now; 0: none (not EEVDF's)
  std::string message;          // one line for the log: what was obtained, or why not
};

// Asks for `slice` (the kernel clamps it to 0.1..100 ms) for the calling thread, keeping its
// policy and nice value. A real-time or deadline thread is left alone.
SliceRequest request_scheduler_slice(std::chrono::nanoseconds slice);

// The calling thread's slice as the kernel reports it (ns); 0 on a kernel without custom slices.
std::uint64_t current_scheduler_slice_ns();

}  // namespace fogbench::daemon
