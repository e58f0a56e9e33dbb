// What the plant link is doing, as `status.plant` reports it (an internal header of daemon/src/,
// used by plant_link.cpp and its tests): idle, connecting, or sending a run, and whether that
// transaction is stalled, i.e. has made no progress (no statement answered, no chunk of COPY
// data taken) for `stall_s` seconds. Pure: the times are steady-clock seconds given by the caller.
#pragma once

#include <cstdint>
#include <string>

namespace fogbench::daemon {

struct PlantActivity {
  enum class Phase { idle, connecting, sending, stopped };
  Phase phase = Phase::idle;
  std::int64_t run_id = 0;   // the run being sent (Phase::sending)
  double began_s = 0;        // steady s: the phase began
  double progress_s = 0;     // steady s: the last progress within it (its beginning at first)
};

struct PlantLinkState {
  std::string state;        // "idle", "connecting", "sending", "stalled" or "stopped"
  bool stalled = false;     // connecting or sending, and no progress for stall_s or longer
  std::int64_t run_id = 0;  // the run being sent, 0 when none
  double busy_s = 0;        // s since the connection attempt or the run's transaction began
  double quiet_s = 0;       // s since the last progress (0 when idle)
};

inline PlantLinkState describe(const PlantActivity& a, double now_s, double stall_s) {
  PlantLinkState s;
  switch (a.phase) {
    case PlantActivity::Phase::idle: s.state = "idle"; return s;
    case PlantActivity::Phase::stopped: s.state = "stopped"; return s;
    case PlantActivity::Phase::connecting: s.state = "connecting"; break;
    case PlantActivity::Phase::sending:
      s.state = "sending";
      s.run_id = a.run_id;
      break;
  }
  // A clock read before the phase was noted (another thread) counts as no time at all.
  s.busy_s = now_s > a.began_s ? now_s - a.began_s : 0;
  s.quiet_s = now_s > a.progress_s ? now_s - a.progress_s : 0;
  if (s.quiet_s >= stall_s) {
    s.stalled = true;
    s.state = "stalled";
  }
  return s;
}

}  // namespace fogbench::daemon
