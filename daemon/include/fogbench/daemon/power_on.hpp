// When each gyro was powered on, as the daemon sees it in its frames, so every sample can carry
// the time since its gyro's power-on (RunData::since_power_on_s, the term language's `ton`).
//
// A gyro gives no power-on message: the daemon infers it from the frames. A unit is off once
// its frames have been silent for `gap_s` (2 s) of read periods with the bus connected; frames
// after that are a power-on, dated to the start of the period they first appeared in (so the
// time since power-on is late by under one period). A unit sending from the daemon's first
// periods was powered on before the daemon could see it: its power-on is unknown, never
// guessed. Periods in which the gyro was not read (its link down, the loop late) are no
// silence; `gap_s` of them in a row lose the power-on (a restart could hide in them).
// Pure: the station feeds it one period at a time. docs/daemon.md "Power-on".
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string_view>
#include <vector>

namespace fogbench::daemon {

// Silence, in daemon seconds, after which a unit counts as powered off.
inline constexpr double kPowerGapS = 2.0;

class PowerWatch {
 public:
  enum class Edge {
    none,
    power_on,  // frames after a silence, the first power-on the daemon sees of this unit
    restart,   // frames after a silence of a unit seen sending before: a power cycle
    power_off, // the unit has been silent for gap_s
    lost,      // not read for gap_s: the power-on is no longer known
  };

  explicit PowerWatch(std::size_t units, double gap_s = kPowerGapS, double period_s = 1.0);

  // One acquisition period ending at clock_s (daemon seconds): per unit the frames that came in
  // it (well-formed or corrupt: anything the gyro sent), or nullopt when the gyro was not read.
  // Returns what changed, per unit.
  std::vector<Edge> update(double clock_s, std::span<const std::optional<std::uint32_t>> frames);

  // Daemon seconds since the unit's power-on at clock_s; empty when the daemon did not see it.
  std::optional<double> since_power_on_s(std::size_t unit, double clock_s) const;
  std::optional<double> powered_on_at_s(std::size_t unit) const { return units_.at(unit).on_at_s; }
  std::size_t units() const { return units_.size(); }

 private:
  struct Unit {
    double silent_s = 0;        // read and silent since ...
    double unread_s = 0;        // not read since ...
    bool off = false;           // silent for gap_s: the next frames are a power-on
    bool seen_sending = false;  // frames seen at least once
    std::optional<double> on_at_s;
  };
  std::vector<Unit> units_;
  double gap_s_;
  double period_s_;
};

std::string_view to_string(PowerWatch::Edge e);

}  // namespace fogbench::daemon
