// One verdict per serial (issue 24 point 1): how the station decides it, once, by one rule, and
// how everything that shows it reads it back (storage/verdict.hpp keeps it). Two rules:
//   plan      the plan that qualified the unit: every limit with its line, what was measured,
//             met or not; pass, marginal (a `continue` limit not met), fail (a stop limit, a
//             failed retest, a failed analysis) or incomplete (the plan ended first);
//   analysis  a bare verify run: the verification's checks against the analysis settings
//             (model::verify's verdict, with the limits stored with it).
// A run a plan started never gets an analysis verdict: its unit's verdict is the plan's.
// The certificate shows the serial's latest verdict when it was decided on the certified model,
// a fail or incomplete whatever the model (a unit a plan failed is never certified pass), and
// "not verified" for a model fitted after the last decision.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "fogbench/storage/runs.hpp"
#include "fogbench/storage/verdict.hpp"

namespace fogbench::daemon::verdict {

// The verification's three checks (its `result` JSON as model::to_json and analysis.cpp store
// it): {check, value, limit, rule, met}; a limit the verdict was stored without is null with
// "(limits not recorded)" in its rule, never today's configuration.
nlohmann::json analysis_checks(const nlohmann::json& result);

// The plan that started the run (its first command event is a plan's step), if one did.
std::optional<std::int64_t> plan_of_run(const storage::RunDetail& run);

// The analysis rule's verdict of a bare verify run's unit, from its stored verification.
storage::NewVerdict from_verification(const std::string& serial, std::int64_t run_id, int unit_index,
                                      std::int64_t model_id, const nlohmann::json& result);

// One axis of a three-axis unit as verified: its axis ("x", "y", "z"), the model it was verified
// against (its own) and its stored verification result.
struct AxisVerification {
  std::string axis;
  std::int64_t model_id = 0;
  nlohmann::json result;
};

// The worse of two verdicts: fail, incomplete, marginal, pass from worst to best.
std::string worst(const std::string& a, const std::string& b);

// The analysis rule's verdict of a bare verify run's three-axis unit: each axis judged as
// from_verification judges a one-axis unit, the unit's verdict the worst of its axes. The row's
// model is x's (the serial's current model, the one a certificate names); its limits are every
// axis' checks, each with its `axis`, its reasons each axis' prefixed "axis y: ", and axes_json
// each axis' {axis, verdict, model_id, limits, reasons}.
storage::NewVerdict from_axis_verifications(const std::string& serial, std::int64_t run_id, int unit_index,
                                            const std::vector<AxisVerification>& axes);

// The plan rule's verdict of one unit: `unit` is the unit's entry of the plan runner's progress
// (serial, verdict, measurements, reasons), `runs` the progress' runs ({run_id, units}). Empty
// when the unit never ran (no run to attach it to).
// A three-axis unit's entry also has `axis_evidence` ({x|y|z: {verdict, reasons}}: what the
// plan runner judged on each axis, every limit on x, y and z, its measurements each with their
// `axis`): its axes_json is then each axis' {axis, verdict, model_id (axis_models'), limits (its
// measurements), reasons}, as from_axis_verifications' are; an axis is incomplete when the unit
// is (the plan ended first) unless it failed, and also when the unit carries `dropped_at_step`
// (dropped on another axis before the plan's last step: the later steps never ran). The unit's verdict is the plan's, which is the
// worst of its axes' (the runner drops the unit exactly when a failure makes an axis fail).
std::optional<storage::NewVerdict> from_plan(std::int64_t plan_id, const std::string& plan_name,
                                             const std::string& plan_text, const nlohmann::json& unit,
                                             const nlohmann::json& runs, std::optional<std::int64_t> model_id,
                                             const std::map<std::string, std::int64_t>& axis_models = {});

// A stored verdict as the socket, the certificate and the plant show it; a three-axis unit's
// with its `axes` (storage's axes_json), a one-axis unit's without.
nlohmann::json to_json(const storage::VerdictRecord& v);

// The verdict a certificate of `model_id` carries, and the decision it comes from (null when
// "not verified"), with a note when the decision was about another model.
struct Certified {
  std::string verdict;  // pass | marginal | fail | incomplete | not verified
  nlohmann::json qualification;
};
Certified certified(const std::optional<storage::VerdictRecord>& latest, std::int64_t model_id);

}  // namespace fogbench::daemon::verdict
