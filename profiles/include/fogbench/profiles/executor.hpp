// Runs a Profile against the readings of a run: what setpoint to command now, which step
// and phase the run is in, and whether a settle has been met or has timed out. Pure and
// clock-free: the caller passes the time, so a whole profile is tested in milliseconds.
#pragma once

#include <cstddef>
#include <deque>
#include <optional>
#include <string>
#include <vector>

#include "fogbench/profiles/profile.hpp"

namespace fogbench::profiles {

// One unit's coil thermistors, degC. A non-finite value means "not read this time".
struct CoilTemps {
  double t1_c = 0.0;  // coil centre
  double t2_c = 0.0;  // coil outer wall
};

// What the executor sees at one update. Only settles read it.
struct Readings {
  double chamber_c = 0.0;        // the chamber's process value (air), degC
  std::vector<CoilTemps> coils;  // one per unit under test; may be empty
};

struct ExecutorStatus {
  double setpoint_c = 0.0;    // the setpoint to command now
  Phase phase = Phase::hold;  // hold after the last step
  std::size_t step_index = 0; // the current step (the last one once finished)
  int step_line = 0;          // its source line
  double step_elapsed_s = 0.0;  // time since the current step began, s
  double remaining_s = 0.0;   // estimate: the rest of this step plus the nominal time of
                              // the steps after it (settles at their `for` time), s
  bool finished = false;      // every step is done
  bool failed = false;        // a settle timed out; the run should stop
  std::string failure_reason; // empty unless failed
};

// Steps through a profile. update() is called with a non-decreasing elapsed time since the
// profile's start (about every second, not necessarily exactly):
//  - `setpoint` steps take no time; `hold` and `ramp` steps end at exact times computed from
//    their start, so the timeline does not drift with the call rate: a step that ends
//    between two calls hands over at its exact end time and the next step's setpoint is
//    computed from there.
//  - a `settle` is judged on the readings passed at each call: it ends at the first call at
//    which its readings have met the criteria at every call for at least its `for` time; it
//    fails at the first call at or after its timeout that does not end it.
// After finishing or failing, the status no longer changes except for step_elapsed_s.
class Executor {
 public:
  explicit Executor(Profile profile);

  ExecutorStatus update(double elapsed_s, const Readings& readings);

  const Profile& profile() const { return profile_; }

 private:
  // A reading kept for the slope estimate: the chamber, then t1, t2 of every unit.
  struct Sample {
    double time_s;
    std::vector<double> values_c;
  };

  bool settled_now(const SettleStep& s, const Readings& r, std::string* why_not) const;
  std::optional<double> slope_c_per_min(std::size_t channel) const;
  void begin_step(std::size_t index, double start_s);
  ExecutorStatus status(double now_s) const;

  Profile profile_;
  // Per step, from the nominal plan: the setpoint at its start and its nominal length.
  std::vector<double> start_setpoint_c_;
  std::vector<double> nominal_s_;
  std::vector<double> nominal_after_s_;  // sum of nominal_s_ of the steps after it
  std::vector<Phase> phase_;

  std::size_t index_ = 0;
  double step_start_s_ = 0.0;
  double setpoint_c_ = 0.0;
  double last_time_s_ = 0.0;
  std::optional<double> stable_since_s_;  // current settle: criteria met at every call since
  bool finished_ = false;
  bool failed_ = false;
  std::string failure_reason_;
  std::deque<Sample> history_;  // the last slope_window_s of readings
};

}  // namespace fogbench::profiles
