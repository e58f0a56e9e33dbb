// Power-on of each gyro from its frames' own evidence; see power_on.hpp.
#include "fogbench/daemon/power_on.hpp"

#include <cassert>

namespace fogbench::daemon {

PowerWatch::PowerWatch(std::size_t units, double gap_s, double period_s)
    : units_(units), gap_s_(gap_s), period_s_(period_s) {
  assert(gap_s > 0 && period_s > 0);
}

std::vector<PowerWatch::Edge> PowerWatch::update(double clock_s, std::span<const std::optional<GyroEvidence>> periods) {
  std::vector<Edge> edges(units_.size(), Edge::none);
  for (std::size_t i = 0; i < units_.size(); ++i) {
    Unit& u = units_[i];
    const std::optional<GyroEvidence> e = i < periods.size() ? periods[i] : std::nullopt;
    if (!e) {
      u.link_down_s += period_s_;
      if (u.link_down_s >= gap_s_ && u.on_at_s) {
        u.on_at_s.reset();
        edges[i] = Edge::lost;
      }
      continue;
    }
    u.link_down_s = 0;
    if (e->read && e->frames == 0 && !u.seen_sending) u.heard_silent = true;
    if (e->starts > 0 && (u.seen_sending || u.heard_silent)) {
      // The gyro says it started: in this period, whenever its frames were read.
      u.on_at_s = clock_s - period_s_;
      edges[i] = u.seen_sending ? Edge::restart : Edge::power_on;
    }
    if (e->frames > 0) u.seen_sending = true;
  }
  return edges;
}

std::optional<double> PowerWatch::since_power_on_s(std::size_t unit, double clock_s) const {
  const auto& on = units_.at(unit).on_at_s;
  if (!on) return std::nullopt;
  return clock_s - *on;
}

std::string_view to_string(PowerWatch::Edge e) {
  switch (e) {
    case PowerWatch::Edge::none: return "none";
    case PowerWatch::Edge::power_on: return "power_on";
    case PowerWatch::Edge::restart: return "restart";
    case PowerWatch::Edge::lost: return "lost";
  }
  return "?";
}

}  // namespace fogbench::daemon
