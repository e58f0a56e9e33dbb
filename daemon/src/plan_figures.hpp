// What a plan's limits measure on one unit's run (docs/plans.md "Limits"), as pure functions of
// the run (and the model): the plan runner judges these figures against the limits
// (plan_runner.cpp). Each gives its value, or no value and the reason in its note.
#pragma once

#include <optional>
#include <string>

#include "fogbench/model/model.hpp"
#include "fogbench/model/run.hpp"

namespace fogbench::daemon::plan_figures {

// Four significant digits, for the reasons people read ("1.863"); the measurements keep the value.
std::string short_number(double v);

// The compensated output's largest distance from its mean, deg/h (flagged samples left out).
std::optional<double> peak_excursion_dph(const model::Model& m, const model::RunData& run);

// The Allan figures of the unit's raw output (1 Hz): ARW, deg/sqrt(h), and bias instability,
// deg/h, or why not.
struct AllanFigures {
  std::optional<double> arw, bias_instability;
  std::string note;
};
AllanFigures allan_figures(const model::RunData& run);

// The scale factor's measurements of one unit's run, from one model::sf::fit over the run's
// turning plateaus: |tc|, ppm/degC, with the signed value and its 1 sigma in the note; the worst
// plateau's nonlinearity, ppm of full-scale output, and its worst |asymmetry|, ppm, each with the
// plateau in the note. No value and the reason when the fit fails (no rate data, too few
// plateaus, a plateau the fit refuses) or tc is not identified.
struct SfFigures {
  std::optional<double> abs_tc_ppm_per_c, nonlinearity_ppm, abs_asymmetry_ppm;
  std::string tc_note, nonlinearity_note, asymmetry_note;
};
SfFigures sf_figures(const model::RunData& run);

}  // namespace fogbench::daemon::plan_figures
