// Power-on of each gyro from its frames; see power_on.hpp.
#include "fogbench/daemon/power_on.hpp"

#include <cassert>

namespace fogbench::daemon {

PowerWatch::PowerWatch(std::size_t units, double gap_s, double period_s)
    : units_(units), gap_s_(gap_s), period_s_(period_s) {
  assert(gap_s > 0 && period_s > 0);
}

std::vector<PowerWatch::Edge> PowerWatch::update(double clock_s, std::span<const std::optional<std::uint32_t>> frames) {
  std::vector<Edge> edges(units_.size(), Edge::none);
  for (std::size_t i = 0; i < units_.size(); ++i) {
    Unit& u = units_[i];
    const std::optional<std::uint32_t> f = i < frames.size() ? frames[i] : std::nullopt;
    if (!f) {
      u.unread_s += period_s_;
      if (u.unread_s >= gap_s_ && u.on_at_s) {
        u.on_at_s.reset();
        edges[i] = Edge::lost;
      }
      continue;
    }
    const bool long_unread = u.unread_s >= gap_s_;
    u.unread_s = 0;
    if (*f == 0) {
      u.silent_s += period_s_;
      if (u.silent_s >= gap_s_ && !u.off) {
        u.off = true;
        // Off from the daemon's start is not an edge: nothing was on.
        if (u.seen_sending) edges[i] = Edge::power_off;
        u.on_at_s.reset();
      }
      continue;
    }
    if (u.off && !long_unread) {
      // Frames after a silence seen whole: a power-on in this period.
      u.on_at_s = clock_s - period_s_;
      edges[i] = u.seen_sending ? Edge::restart : Edge::power_on;
    } else if (u.off && long_unread) {
      // It came on while the daemon could not read it: when is not known.
      u.on_at_s.reset();
    }
    u.off = false;
    u.silent_s = 0;
    u.seen_sending = true;
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
    case PowerWatch::Edge::power_off: return "power_off";
    case PowerWatch::Edge::lost: return "lost";
  }
  return "?";
}

}  // namespace fogbench::daemon
