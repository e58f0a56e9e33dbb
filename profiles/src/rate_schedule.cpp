#include "fogbench/profiles/rate_schedule.hpp"

#include <algorithm>
#include <cmath>

namespace fogbench::profiles {

RateSchedule::RateSchedule(const Profile& profile) {
  // The parser has put each step after the hold it runs in, in source order: a plateau's
  // sequence starts at the hold's start and each step at the previous one's end.
  double t_s = 0.0;
  std::optional<std::size_t> plateau;
  for (std::size_t i = 0; i < profile.rate_steps.size(); ++i) {
    const RateStep& r = profile.rate_steps[i];
    if (plateau != r.plateau) {
      plateau = r.plateau;
      t_s = 0.0;
    }
    steps_.push_back({r.plateau, t_s, t_s + r.duration_s, r.rate_dps, i});
    t_s += r.duration_s;
  }
}

double RateSchedule::max_abs_rate_dps() const {
  double m = 0.0;
  for (const Planned& p : steps_) m = std::max(m, std::abs(p.rate_dps));
  return m;
}

RateCommand RateSchedule::at(std::size_t step_index, double step_elapsed_s) const {
  if (!std::isfinite(step_elapsed_s) || step_elapsed_s < 0.0) return {};
  for (const Planned& p : steps_) {
    if (p.plateau != step_index) continue;
    if (step_elapsed_s >= p.start_s && step_elapsed_s < p.end_s) return {p.rate_dps, p.index};
  }
  return {};
}

RateCommand RateSchedule::at(const ExecutorStatus& status) const {
  if (status.finished || status.failed) return {};
  return at(status.step_index, status.step_elapsed_s);
}

}  // namespace fogbench::profiles
