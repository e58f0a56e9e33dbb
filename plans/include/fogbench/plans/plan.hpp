// Qualification plans (docs/plans.md): the hand-written text format of an ordered list of
// steps (a profile and its purpose) and the acceptance limits a unit must meet, its parser with
// line and column errors like the profiles', and the judgement of one measurement against its
// limit. Pure: no files, no daemon; the daemon checks what needs the station (the profiles
// exist, a model is on file for a verify step that no fit step precedes).
#pragma once

#include <cstdint>
#include <expected>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace fogbench::plans {

// Why a step's run is recorded. fit and verify are the daemon's run purposes (the fit step's
// model is the one the later verify steps use); soak and custom runs are recorded without the
// automatic analysis (a soak gives the Allan figures).
enum class StepPurpose : std::uint8_t { fit, verify, soak, custom };
std::string_view to_string(StepPurpose p);
std::optional<StepPurpose> step_purpose_from_string(std::string_view s);

struct Step {
  std::string profile;  // a profile name of the station's profile directory
  StepPurpose purpose = StepPurpose::fit;
  int line = 0;         // 1-based source line
};

// What a limit judges. The verify measurements come from each verify step's verification; the
// fit ones from each fit step's model (sensitivity) or its run (Allan figures, also soak runs).
enum class Measurement : std::uint8_t {
  comp_raw,              // compensated std / raw std (the paper's rule: < 0.2), no unit
  noise_factor,          // compensated std / the std the model's AR noise implies, no unit
  fail_s,                // the longest failing interval (61 s residual mean beyond 3 sigma_a), s
  peak_excursion,        // max |compensated output - its mean| over the run, deg/h
  sensitivity,           // a fitted term's coefficient, deg/h per unit of the term
  arw,                   // angle random walk, deg/sqrt(h) (Allan, IEEE 952)
  bias_instability,      // bias instability, deg/h (Allan, IEEE 952)
  firmware,              // the fitted model has a firmware form (`limit firmware required`): 1 yes, 0 no
  // The magnitude |tc| of the scale factor's temperature sensitivity, ppm/degC (model::sf::fit
  // of the run's rate plateaus; `limit sf_tc_ppm_per_c < 20` means |tc| < 20 ppm/degC). Measured
  // in the fit and verify steps whose profile has rate steps; the daemon refuses a plan with
  // this limit and no such step.
  sf_tc_ppm_per_c,
  // The scale factor's worst nonlinearity over the run's rate plateaus, ppm of full-scale output
  // (IEEE 952: the largest residual of the least-squares line, model::sf::Plateau), and its
  // worst asymmetry |sf+ - sf-| / sf, ppm; measured where sf_tc_ppm_per_c is.
  sf_nonlinearity_ppm,
  sf_asymmetry_ppm,
};
std::string_view to_string(Measurement m);
// Which step purposes give the measurement: verify steps, fit steps, fit and soak steps, or fit
// and verify steps (the sf_* measurements, only where the step's profile has rate steps).
bool measured_in(Measurement m, StepPurpose p);
// Whether the measurement is the scale factor's (sf_*): measured only in a fit or verify step
// whose profile has rate steps, and refused on a plan without one.
bool needs_rate_steps(Measurement m);
// The unit a value of the measurement may be written with ("" when it has none).
std::string_view unit_of(Measurement m);

enum class OnFail : std::uint8_t {
  stop,       // the unit fails and is dropped from the rest of the plan
  go_on,      // the unit is marginal and goes on (`continue` in the text)
  retest,     // the step is run once more for the unit; a second failure stops it
};
std::string_view to_string(OnFail a);

// `<` `<=` `>` `>=` a bound, `within lo .. hi` (inclusive), or `required` (firmware only: the
// measurement is 1 when the model has what is required, 0 when not).
enum class Compare : std::uint8_t { lt, le, gt, ge, within, required };

struct Limit {
  Measurement measurement = Measurement::comp_raw;
  std::string term;   // sensitivity only: the term's name as the model prints it, e.g. "d(T1)"
  Compare compare = Compare::lt;
  double value = 0.0;             // the bound (lo for within)
  double high = 0.0;              // within only
  OnFail on_fail = OnFail::stop;
  int line = 0;
  // "comp_raw < 0.2", "sensitivity d(T1) within -3 .. -2", "firmware required"
  std::string describe() const;
  // Whether a measured value meets the limit (a non-finite value never does).
  bool met(double measured) const;
  // The measurement's name with its term: "comp_raw", "sensitivity d(T1)".
  std::string name() const;
};

struct Plan {
  std::string name;  // `plan <name>`, or the source's stem
  std::vector<Step> steps;
  std::vector<Limit> limits;
  std::string source;
};

struct PlanError {
  std::string source;
  int line = 0;     // 1-based; 0 when not about a line
  int column = 0;   // 1-based byte column; 0 with line 0
  std::string message;
  std::string line_text;
  std::string to_string() const;  // "source:line:column: message"
  std::string excerpt() const;    // the line and a caret under the column
};

// Parses a plan. Errors name the line and column of the offending word; parsing stops at the
// first. Also refused: no step, a limit on a measurement that no step of the plan produces, a
// limit given twice for the same measurement (and term).
std::expected<Plan, PlanError> parse_plan(std::string_view text, std::string_view source = "plan");

}  // namespace fogbench::plans
