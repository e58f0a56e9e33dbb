// One verdict per serial: the rules' rows and how they are read back (verdict.hpp).
#include "verdict.hpp"

#include "fogbench/model/sha256.hpp"

namespace fogbench::daemon::verdict {

using nlohmann::json;

namespace {
json check(const json& res, const char* name, const char* value_key, const char* limit_key, const std::string& rule) {
  const json value = res.value(value_key, json(nullptr));
  if (!res.contains(limit_key) || !res[limit_key].is_number())
    return {{"check", name}, {"value", value}, {"limit", nullptr}, {"rule", rule + " (limits not recorded)"},
            {"met", nullptr}};
  const double limit = res[limit_key].get<double>();
  json met = nullptr;
  if (value.is_number()) met = rule == "value <= limit" ? value.get<double>() <= limit : value.get<double>() < limit;
  return {{"check", name}, {"value", value}, {"limit", limit}, {"rule", rule}, {"met", met}};
}

json parse_array(const std::string& text) {
  json j = json::parse(text, nullptr, false);
  return j.is_array() ? j : json::array();
}
}  // namespace

json analysis_checks(const json& result) {
  return json::array({check(result, "compensated std / raw std", "ratio", "threshold", "value < limit"),
                      check(result, "compensated std / model noise std", "noise_factor", "max_noise_factor",
                            "value <= limit"),
                      check(result, "longest failing interval, s", "longest_fail_s", "max_fail_s", "value < limit")});
}

std::optional<std::int64_t> plan_of_run(const storage::RunDetail& run) {
  for (const auto& e : run.events) {
    if (e.kind != storage::EventKind::command) continue;
    const json d = json::parse(e.detail_json, nullptr, false);
    if (d.is_object() && d.value("cmd", "") == "plan.step" && d.contains("plan_id") && d["plan_id"].is_number_integer())
      return d["plan_id"].get<std::int64_t>();
    return std::nullopt;  // only the first command started the run
  }
  return std::nullopt;
}

storage::NewVerdict from_verification(const std::string& serial, std::int64_t run_id, int unit_index,
                                      std::int64_t model_id, const json& result) {
  storage::NewVerdict v;
  v.serial = serial;
  v.run_id = run_id;
  v.unit_index = unit_index;
  v.model_id = model_id;
  const std::string said = result.value("verdict", std::string());
  v.verdict = storage::is_verdict_name(said) && said != "incomplete" ? said : result.value("pass", false) ? "pass" : "fail";
  v.rule = "analysis";
  json limits = json::array();
  for (const auto& c : analysis_checks(result))
    limits.push_back({{"limit", c["rule"].get<std::string>()}, {"measurement", c["check"]}, {"value", c["value"]},
                      {"bound", c["limit"]}, {"met", c["met"]}, {"run_id", run_id}});
  v.limits_json = limits.dump();
  v.reasons_json = (result.contains("reasons") && result["reasons"].is_array() ? result["reasons"] : json::array()).dump();
  return v;
}

std::string worst(const std::string& a, const std::string& b) {
  auto rank = [](const std::string& v) { return v == "fail" ? 3 : v == "incomplete" ? 2 : v == "marginal" ? 1 : 0; };
  return rank(b) > rank(a) ? b : a;
}

storage::NewVerdict from_axis_verifications(const std::string& serial, std::int64_t run_id, int unit_index,
                                            const std::vector<AxisVerification>& axes) {
  storage::NewVerdict v;
  v.serial = serial;
  v.run_id = run_id;
  v.unit_index = unit_index;
  v.rule = "analysis";
  v.verdict = "pass";
  json limits = json::array(), reasons = json::array(), evidence = json::array();
  for (const auto& a : axes) {
    const storage::NewVerdict one = from_verification(serial, run_id, unit_index, a.model_id, a.result);
    v.verdict = worst(v.verdict, one.verdict);
    if (a.axis == "x" || !v.model_id) v.model_id = a.model_id;
    json axis_limits = parse_array(one.limits_json);
    for (auto& l : axis_limits) {
      l["axis"] = a.axis;
      limits.push_back(l);
    }
    const json axis_reasons = parse_array(one.reasons_json);
    for (const auto& r : axis_reasons) reasons.push_back("axis " + a.axis + ": " + (r.is_string() ? r.get<std::string>() : r.dump()));
    evidence.push_back({{"axis", a.axis}, {"verdict", one.verdict}, {"model_id", a.model_id},
                        {"limits", parse_array(one.limits_json)}, {"reasons", axis_reasons}});
  }
  v.limits_json = limits.dump();
  v.reasons_json = reasons.dump();
  v.axes_json = evidence.dump();
  return v;
}

std::optional<storage::NewVerdict> from_plan(std::int64_t plan_id, const std::string& plan_name,
                                             const std::string& plan_text, const json& unit, const json& runs,
                                             std::optional<std::int64_t> model_id,
                                             const std::map<std::string, std::int64_t>& axis_models) {
  const std::string serial = unit.value("serial", std::string());
  // The unit's last run in the plan decides it; its index there is its place in the run's units.
  std::optional<std::int64_t> run_id;
  int unit_index = 0;
  for (const auto& r : runs) {
    if (!r.contains("units") || !r["units"].is_array() || !r.contains("run_id") || !r["run_id"].is_number_integer())
      continue;
    for (std::size_t i = 0; i < r["units"].size(); ++i)
      if (r["units"][i] == serial) {
        run_id = r["run_id"].get<std::int64_t>();
        unit_index = static_cast<int>(i);
      }
  }
  if (!run_id) return std::nullopt;
  storage::NewVerdict v;
  v.serial = serial;
  v.run_id = *run_id;
  v.unit_index = unit_index;
  v.model_id = model_id;
  const json said = unit.value("verdict", json(nullptr));
  v.verdict = said.is_string() && storage::is_verdict_name(said.get<std::string>()) ? said.get<std::string>() : "incomplete";
  v.rule = "plan";
  v.plan_id = plan_id;
  v.plan_name = plan_name;
  v.plan_sha256 = model::sha256_hex(plan_text);
  v.limits_json = (unit.contains("measurements") && unit["measurements"].is_array() ? unit["measurements"] : json::array()).dump();
  v.reasons_json = (unit.contains("reasons") && unit["reasons"].is_array() ? unit["reasons"] : json::array()).dump();
  if (unit.contains("axis_evidence") && unit["axis_evidence"].is_object()) {
    const json& evidence = unit["axis_evidence"];
    json axes = json::array();
    for (const char* axis : {"x", "y", "z"}) {
      const json e = evidence.contains(axis) && evidence[axis].is_object() ? evidence[axis] : json::object();
      const json said_axis = e.value("verdict", json(nullptr));
      std::string axis_verdict =
          said_axis.is_string() && storage::is_verdict_name(said_axis.get<std::string>()) ? said_axis.get<std::string>() : "pass";
      if (v.verdict == "incomplete") axis_verdict = worst(axis_verdict, "incomplete");
      json axis_reasons = e.contains("reasons") && e["reasons"].is_array() ? e["reasons"] : json::array();
      // Dropped on another axis before the plan's last step: the steps after it never ran, so an
      // axis that had met every limit so far is not a pass, it was not measured to the end.
      if (const json at = unit.value("dropped_at_step", json(nullptr)); at.is_number_integer() && axis_verdict != "fail") {
        axis_verdict = worst(axis_verdict, "incomplete");
        axis_reasons.push_back("the unit was dropped at step " + std::to_string(at.get<int>()) +
                               " on another axis: the steps after it did not run");
      }
      json limits = json::array();
      if (unit.contains("measurements") && unit["measurements"].is_array())
        for (const auto& m : unit["measurements"])
          if (m.is_object() && m.value("axis", "") == axis) limits.push_back(m);
      const auto model = axis_models.find(axis);
      axes.push_back({{"axis", axis},
                      {"verdict", axis_verdict},
                      {"model_id", model != axis_models.end() ? json(model->second) : json(nullptr)},
                      {"limits", limits},
                      {"reasons", axis_reasons}});
    }
    v.axes_json = axes.dump();
  }
  return v;
}

json to_json(const storage::VerdictRecord& v) {
  json plan = nullptr;
  if (v.plan_id) plan = {{"id", *v.plan_id}, {"name", v.plan_name}, {"sha256", v.plan_sha256}};
  json j = {{"verdict_id", v.id},
            {"serial", v.serial},
            {"verdict", v.verdict},
            {"rule", v.rule},
            {"plan", plan},
            {"run_id", v.run_id},
            {"unit", v.unit_index},
            {"model_id", v.model_id ? json(*v.model_id) : json(nullptr)},
            {"limits", parse_array(v.limits_json)},
            {"reasons", parse_array(v.reasons_json)},
            {"decided_at", v.decided_at}};
  if (!v.axes_json.empty()) j["axes"] = parse_array(v.axes_json);  // a three-axis unit's only
  return j;
}

Certified certified(const std::optional<storage::VerdictRecord>& latest, std::int64_t model_id) {
  if (!latest) return {"not verified", nullptr};
  json q = to_json(*latest);
  if (latest->model_id == model_id) return {latest->verdict, q};
  if (latest->verdict == "fail" || latest->verdict == "incomplete") {
    q["note"] = latest->model_id ? "decided on model " + std::to_string(*latest->model_id) + ", not this one: it holds for the serial"
                                 : std::string("decided with no model: it holds for the serial");
    return {latest->verdict, q};
  }
  return {"not verified", nullptr};  // the model was fitted after the last decision
}

}  // namespace fogbench::daemon::verdict
