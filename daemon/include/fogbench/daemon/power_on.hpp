// When each gyro was powered on, as the gyro itself tells it in its frames, so every sample can
// carry the time since its gyro's power-on (RunData::since_power_on_s, the term language's `ton`).
//
// A power-on is decided only from the gyro's own evidence: a frame that begins a start-up (the
// status bit `warming_up` rising, the counter from 0; drivers::GyroSample::starts,
// docs/can-frames.md "Power-on"). It is dated to the start of the period that frame was read in.
// Silence is no evidence: frames that come late (a busy host, a paused or late loop, a bench
// that falls behind) keep their counter and carry no `warming_up`, so they never make a
// power-on, a restart or a power-off, and the time since power-on only grows. A unit's first
// start-up is its power-on only when the daemon had read the bus and heard nothing from the unit
// before (it was listening when the unit came on); a unit sending from the daemon's first periods
// (a paced world's first frames included) was powered on before the daemon could see it: its
// power-on is unknown, never guessed. Periods in which the bus link was down lose frames, and a whole
// start-up could hide in them: `gap_s` of those in a row lose the power-on.
// Pure: the station feeds it one period at a time. docs/daemon.md "Power-on".
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string_view>
#include <vector>

namespace fogbench::daemon {

// Link-down time, in daemon seconds, after which a unit's power-on is no longer known.
inline constexpr double kPowerGapS = 2.0;

// What one unit's frames of one period say (from drivers::GyroSample).
struct GyroEvidence {
  std::uint32_t frames = 0;  // anything it sent (well-formed or corrupt)
  std::uint32_t starts = 0;  // frames that begin a power-on
  // The bus was read for the period (false: the loop late, a paced world that did not step).
  bool read = true;
};

class PowerWatch {
 public:
  enum class Edge {
    none,
    power_on,  // a start-up of a unit not seen sending before: the first power-on the daemon sees
    restart,   // a start-up of a unit seen sending before: a power cycle
    lost,      // the bus link down for gap_s: the power-on is no longer known
  };

  explicit PowerWatch(std::size_t units, double gap_s = kPowerGapS, double period_s = 1.0);

  // One acquisition period ending at clock_s (daemon seconds): per unit what its frames of the
  // period say, or nullopt when the bus link was down (frames sent meanwhile are lost). A
  // period with no frames (the loop or the bench late, the gyro off) changes nothing.
  // Returns what changed, per unit.
  std::vector<Edge> update(double clock_s, std::span<const std::optional<GyroEvidence>> periods);

  // Daemon seconds since the unit's power-on at clock_s; empty when the daemon did not see it.
  std::optional<double> since_power_on_s(std::size_t unit, double clock_s) const;
  std::optional<double> powered_on_at_s(std::size_t unit) const { return units_.at(unit).on_at_s; }
  std::size_t units() const { return units_.size(); }

 private:
  struct Unit {
    double link_down_s = 0;     // not read since ...
    bool seen_sending = false;  // frames seen at least once
    bool heard_silent = false;  // read and silent before its first frames
    std::optional<double> on_at_s;
  };
  std::vector<Unit> units_;
  double gap_s_;
  double period_s_;
};

std::string_view to_string(PowerWatch::Edge e);

}  // namespace fogbench::daemon
