// The rate table's command over a run: the rate steps of a profile (`rate <r> dps for <d>`, each
// naming the hold it runs in) laid out on their plateaus' timelines. Pure and clock-free, as the
// temperature executor (executor.hpp) is: the caller passes where the profile stands (the step
// and the time since it began, from ExecutorStatus), so the rate follows the temperature
// timeline whatever its settles took.
#pragma once

#include <cstddef>
#include <optional>
#include <vector>

#include "fogbench/profiles/executor.hpp"
#include "fogbench/profiles/profile.hpp"

namespace fogbench::profiles {

// What the table should do now.
struct RateCommand {
  double rate_dps = 0.0;                 // deg/s, signed; 0 at rest
  std::optional<std::size_t> rate_step;  // index in Profile::rate_steps; none: no rate step (rest)
};

class RateSchedule {
 public:
  explicit RateSchedule(const Profile& profile);

  // Whether the profile has any rate step (a table is needed to run it).
  bool empty() const { return steps_.empty(); }
  // The largest |rate| the profile commands, deg/s (0 without rate steps): what a gyro on the
  // table may read beyond its drift.
  double max_abs_rate_dps() const;

  // The command when profile step `step_index` has run for `step_elapsed_s` (s): in a hold with
  // a rate sequence, the rate step in force, the sequence run in order from the hold's start (a
  // time on a step's end belongs to the next step); 0 deg/s before and after the sequence, in
  // any other step, and for a time that is not a finite number >= 0.
  RateCommand at(std::size_t step_index, double step_elapsed_s) const;
  // The same where the temperature executor stands: 0 deg/s once it has finished or failed.
  RateCommand at(const ExecutorStatus& status) const;

 private:
  struct Planned {
    std::size_t plateau = 0;  // index in Profile::steps
    double start_s = 0.0;     // since the hold's start, s
    double end_s = 0.0;
    double rate_dps = 0.0;
    std::size_t index = 0;    // in Profile::rate_steps
  };
  std::vector<Planned> steps_;  // in source order: by plateau, then by start
};

}  // namespace fogbench::profiles
