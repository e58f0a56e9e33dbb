// A recorded thermal run of one gyro: the signals every model computation reads.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <expected>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace fogbench::model {

// The profile phase a sample belongs to. `settle` samples precede the run proper.
enum class Phase : std::uint8_t { unknown = 0, settle, hold, heating, cooling };

std::string_view to_string(Phase p);
std::optional<Phase> phase_from_string(std::string_view s);

// A gyro axis of a three-axis unit (docs/daemon.md "Three-axis units"): x is axis 0, the one a
// one-axis unit has; y and z are axes 1 and 2.
enum class Axis : std::uint8_t { x = 0, y, z };

std::string_view to_string(Axis a);  // "x", "y", "z"
std::optional<Axis> axis_from_string(std::string_view s);

// Quality flags of one sample (bit set), as stored by the daemon and exported in CSV.
namespace flag {
inline constexpr std::uint8_t missing = 1u << 0;       // a signal was not read this second
inline constexpr std::uint8_t frames_lost = 1u << 1;   // the gyro's sequence counter skipped
inline constexpr std::uint8_t out_of_range = 1u << 2;  // a reading outside its plausible range
inline constexpr std::uint8_t link_gap = 1u << 3;      // the chamber link was down
inline constexpr std::uint8_t pv_frozen = 1u << 4;     // the chamber's PV stood still while its setpoint moved
}  // namespace flag

// Column vectors of equal length (optional ones are empty when not recorded).
struct RunData {
  std::string name;                  // where it came from: a file name, "run 12", "sim exp1"
  std::vector<double> time_s;        // sample time, s since the run's start (1 Hz nominal)
  std::vector<double> gyro_dph;      // gyro output, deg/h
  std::vector<double> t1_c;          // coil-centre thermistor, degC
  std::vector<double> t2_c;          // coil outer-wall thermistor, degC
  std::vector<double> setpoint_c;    // chamber setpoint, degC (optional)
  std::vector<double> chamber_c;     // chamber air process value, degC (optional)
  std::vector<Phase> phase;          // profile phase of each sample (optional)
  std::vector<int> step;             // profile step index of each sample (optional)
  std::vector<std::uint8_t> flags;   // quality flags, see `flag` (optional: all good)
  // Time since the gyro's last power-on, s (optional: empty when the recording did not capture
  // it; never guessed). The term language's signal `ton`; CSV column `since_power_on_s`.
  std::vector<double> since_power_on_s;
  // The daemon's live compensated rate, deg/h (optional: empty when the recording has none;
  // NaN where the daemon computed none). Never an input of a fit. CSV column `compensated_dph`.
  std::vector<double> compensated_dph;
  // The rate the rate table was commanded to, deg/s (optional: empty when the run drove no
  // table). Never an input of a drift fit. CSV: written as `rate_in_dps` with `plateau` (the
  // step) and `rate_out_dps` (gyro_dph / 3600), the columns `fogctl scale-factor` reads.
  std::vector<double> rate_in_dps;
  // A three-axis unit's axes 1 and 2 (y, z), deg/h (gyro_dph is axis 0, x), both or neither
  // (optional: empty for a one-axis unit; NaN where the axis sent nothing usable, a sample
  // flagged missing). Not yet an input of any fit. CSV columns `gyro_y_dph`, `gyro_z_dph`.
  std::vector<double> gyro_y_dph;
  std::vector<double> gyro_z_dph;
  // A three-axis unit whose axes each have their own coil thermistors: axis k's centre and
  // outer wall (x, y, z), degC (optional: all empty when the axes share the unit's t1_c, t2_c;
  // else all six filled, x's equal to the recording's t1_c, t2_c). Kept by select_axis, so an
  // axis's model can read another axis's coil (the cross-axis signals T1x..T2z). CSV columns
  // `t1_y_c`, `t2_y_c`, `t1_z_c`, `t2_z_c` (x's are `t1_c`, `t2_c`).
  std::array<std::vector<double>, 3> axis_t1_c, axis_t2_c;
  // The axis gyro_dph holds when select_axis() picked it from a three-axis recording (its
  // gyro_y_dph, gyro_z_dph are then empty); unset: a one-axis run, or a three-axis one not
  // picked, whose gyro_dph is x.
  std::optional<Axis> axis;

  std::size_t size() const { return time_s.size(); }
  bool has_setpoint() const { return !setpoint_c.empty(); }
  bool has_chamber() const { return !chamber_c.empty(); }
  bool has_phase() const { return !phase.empty(); }
  bool has_step() const { return !step.empty(); }
  bool has_flags() const { return !flags.empty(); }
  bool has_power_on() const { return !since_power_on_s.empty(); }
  bool has_compensated() const { return !compensated_dph.empty(); }
  bool has_rate_in() const { return !rate_in_dps.empty(); }
  bool has_axes() const { return !gyro_y_dph.empty(); }
  bool has_axis_thermistors() const { return !axis_t1_c[1].empty(); }
  // True when sample i carries any quality flag.
  bool flagged(std::size_t i) const { return !flags.empty() && flags[i] != 0; }
  // The axis gyro_dph holds: `axis`, else x.
  Axis gyro_axis() const { return axis.value_or(Axis::x); }
};

// The run as the one axis a drift analysis reads: gyro_dph becomes `axis` (from gyro_y_dph or
// gyro_z_dph for y, z), `axis` is set and the three-axis columns are dropped, so every fit,
// prediction and check reads that axis exactly as it reads a one-axis gyro. compensated_dph is
// dropped for y and z (the daemon's live compensation is of x). A one-axis run asked for x is
// returned as it is (`axis` unset: it has no other). With per-axis thermistors, t1_c and t2_c
// become the axis's own (axis_t1_c, axis_t2_c kept whole for the cross-axis signals). Errors, naming the run and the axis: y or
// z of a run without those columns, another axis of a run already picked.
std::expected<RunData, std::string> select_axis(RunData run, Axis axis);

}  // namespace fogbench::model
