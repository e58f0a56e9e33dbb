// Temperature profiles for the thermal chamber: the hand-written text format (see
// docs/profiles.md), its parser, the chamber-limit check and the nominal timeline.
// Pure: no files, no logging; every failure that can happen is a ProfileError value.
#pragma once

#include <cstddef>
#include <cstdint>
#include <expected>
#include <optional>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

namespace fogbench::profiles {

// What the chamber is doing. The daemon maps it onto model::Phase when it records a sample.
enum class Phase : std::uint8_t { settle, hold, heating, cooling };
std::string_view to_string(Phase p);

// A settle with no `timeout` fails after this long, s (2 h: a coil that has not settled by
// then points at a chamber or a mounting problem, not at a slow coil).
inline constexpr double default_settle_timeout_s = 7200.0;
// The slope of a settle reading is a least-squares line through its readings of the last
// slope_window_s, s; it is judged only once those readings span slope_min_span_s, s, so a
// fresh start or a gap in the readings never yields a slope from two close points.
inline constexpr double slope_window_s = 60.0;
inline constexpr double slope_min_span_s = 30.0;

// `setpoint <T> C`: step the setpoint now (takes no time).
struct SetpointStep {
  double temp_c = 0.0;
  int temp_column = 0;  // 1-based column of the temperature, for limit messages
};

// `hold <duration>`: keep the setpoint for a fixed time.
struct HoldStep {
  double duration_s = 0.0;
};

// `ramp to <T> C at <rate> C/min`: move the setpoint linearly from its value at the ramp's
// start to the target; the step ends when it reaches the target.
struct RampStep {
  double target_c = 0.0;
  double rate_c_per_min = 0.0;  // magnitude, > 0; the direction comes from the target
  int target_column = 0;        // 1-based columns of the values, for limit messages
  int rate_column = 0;
};

// Which readings a settle judges.
enum class SettleOn : std::uint8_t {
  chamber,  // the chamber's air (its process value)
  coil,     // every unit's coil-centre and outer-wall thermistors
};

// `settle within <band> C [on chamber|coil] [slope <s> C/min] for <d> [timeout <d>]`: wait
// until the readings stay within band_c of the setpoint (and, if given, the magnitude of
// their slope stays under max_slope_c_per_min) for stable_s without a break. Leaving the
// band restarts the timer, so an overshoot cannot end a soak early.
struct SettleStep {
  double band_c = 0.0;  // half-width, degC, > 0
  SettleOn on = SettleOn::chamber;
  std::optional<double> max_slope_c_per_min;  // degC/min, > 0 when given
  double stable_s = 0.0;                      // the `for` time, s
  double timeout_s = default_settle_timeout_s;
};

enum class StepKind : std::uint8_t { setpoint, hold, ramp, settle };
std::string_view to_string(StepKind k);

struct Step {
  std::variant<SetpointStep, HoldStep, RampStep, SettleStep> action;
  int line = 0;      // 1-based line in the source
  std::string text;  // that line as written, so a later message can quote it
  StepKind kind() const { return static_cast<StepKind>(action.index()); }
};

// `rate <r> dps for <d>`: the rate table at r deg/s (signed; 0 at rest) for d, during the
// `hold` it follows: the rate steps written after a hold are that plateau's rate sequence, run
// in order from the hold's start, and must fit in it. Laid out on the run's timeline by
// RateSchedule (rate_schedule.hpp); fogbenchd drives its configured rate table with them.
struct RateStep {
  double rate_dps = 0.0;     // deg/s, signed
  double duration_s = 0.0;   // s, > 0
  std::size_t plateau = 0;   // index in Profile::steps of the hold it runs in
  int line = 0;              // 1-based line in the source
  int rate_column = 0;       // 1-based column of the rate, for limit messages
  std::string text;          // that line as written
};

struct Profile {
  std::string source_name;  // e.g. "exp1.profile", as given to parse_profile
  std::vector<Step> steps;  // steps[0] is always a SetpointStep
  std::vector<RateStep> rate_steps;  // in source order; each names the hold it runs in
  // The profile's length if every settle is met at its minimum (`for`) time, s.
  double nominal_duration_s() const;
};

// Why a text is not a valid profile, or why a profile does not fit a chamber.
struct ProfileError {
  std::string source;     // the source name given to parse_profile
  int line = 0;           // 1-based; 0 when the error is not about a line (bad limits)
  int column = 0;         // 1-based byte column; 0 with line 0
  std::string message;    // e.g. "expected a temperature unit 'C' after '10', found 'F'"
  std::string line_text;  // the offending line as written, for a caret
  // "source:line:column: message" (just "source: message" when line is 0).
  std::string to_string() const;
  // line_text and, under it, a caret at column (tabs kept so the caret lines up); empty
  // when line is 0.
  std::string excerpt() const;
};

// Parses a profile. source_name only labels messages and the result.
std::expected<Profile, ProfileError> parse_profile(std::string_view text,
                                                   std::string_view source_name);

// What a chamber can do. Bounds are inclusive.
struct ChamberLimits {
  double min_c = 0.0;
  double max_c = 0.0;
  double max_rate_c_per_min = 0.0;
};

// Every setpoint and ramp target inside [min_c, max_c] and every ramp rate at most
// max_rate_c_per_min; the first violation names its line, the value and the limit.
// Limits that are not finite, min_c > max_c or a rate <= 0 are refused (line 0).
std::expected<void, ProfileError> check_limits(const Profile& profile,
                                               const ChamberLimits& limits);

// Every rate step's |rate| at most max_rate_dps (deg/s); the first violation names its line,
// the value and the limit. A max_rate_dps that is not a positive finite number is refused (line 0).
std::expected<void, ProfileError> check_rate_limits(const Profile& profile, double max_rate_dps);

struct NominalPoint {
  double time_s = 0.0;  // since the profile's start, s
  double setpoint_c = 0.0;
  Phase phase = Phase::hold;
  std::size_t step_index = 0;
};

// The setpoint and phase at t = k * dt_s, k = 0 .. ceil(duration / dt_s), with every settle
// met at its `for` time (for simulations and plots). A step begins at its start time, so a
// point on a boundary belongs to the later step; at and after the end the phase is hold at
// the final setpoint. Empty when dt_s is not a positive finite number.
std::vector<NominalPoint> nominal_setpoints(const Profile& profile, double dt_s);

}  // namespace fogbench::profiles
