// A serial's verdict (issue 24, "one verdict"): decided once, by one rule, and kept in the
// table `verdicts` (docs/storage.md). The rule is a qualification plan's limits (the plan that
// qualified the unit: its name, the SHA-256 of its text, every limit with its line and what was
// measured) or, for a bare verify run, the station's analysis settings (the verification's three
// checks and their limits). The serial's verdict is its latest row; the certificate, `run get`,
// the plan report, the panel, the report and the plant all read it from here, none computes its
// own. Plain values; the Store reads and writes them (store_verdicts.cpp).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace fogbench::storage {

// pass | marginal (a `continue` limit was not met) | fail | incomplete (the plan ended before
// the unit finished it: aborted, failed, a run lost).
bool is_verdict_name(std::string_view v);
// plan | analysis
bool is_verdict_rule(std::string_view r);

struct NewVerdict {
  std::string serial;
  std::int64_t run_id = 0;     // the run that decided it: the verification, or the plan's last run of the unit
  int unit_index = 0;          // the serial's unit in that run
  std::optional<std::int64_t> model_id;  // the model judged (none: the unit has no model, e.g. its fit failed)
  std::string verdict;         // is_verdict_name
  std::string rule;            // is_verdict_rule
  std::optional<std::int64_t> plan_id;   // rule plan: the plan, its name and the SHA-256 of its text
  std::string plan_name, plan_sha256;
  // The limits the rule judged, each with its value: a JSON array of objects
  // {limit, line (plans only), measurement, value, unit, met, on_fail, step, run_id}.
  std::string limits_json = "[]";
  std::string reasons_json = "[]";  // why it is not pass, as the plan or the verification said
  // A three-axis unit's verdict, the worst of its axes: each axis' evidence, a JSON array of
  // objects {axis, verdict, model_id, limits, reasons}. Empty (stored NULL) for a one-axis unit.
  std::string axes_json;
};

struct VerdictRecord : NewVerdict {
  std::int64_t id = 0;
  std::string decided_at;  // ISO 8601 UTC
};

}  // namespace fogbench::storage
