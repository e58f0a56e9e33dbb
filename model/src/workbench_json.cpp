// JSON of the workbench's results, for fogctl --json and the daemon's socket. Names carry
// units (_dph deg/h, _c degC, _s s); NaN (not available) is written as null.
#include <cmath>

#include "fogbench/model/json.hpp"
#include "fogbench/model/workbench.hpp"

namespace fogbench::model::workbench {
namespace {

using nlohmann::json;

json num(double v) { return std::isfinite(v) ? json(v) : json(nullptr); }

json series(const std::vector<double>& v) {
  json a = json::array();
  for (double x : v) a.push_back(num(x));
  return a;
}

json table(const Table1& t) { return to_json(t); }

}  // namespace

json to_json(const FailInterval& f) {
  return {{"phase", std::string(to_string(f.phase))},
          {"step", f.step < 0 ? json(nullptr) : json(f.step)},
          {"start_s", f.start_s},
          {"duration_s", f.duration_s},
          {"mean_err_dph", num(f.mean_err_dph)},
          {"peak_err_dph", num(f.peak_err_dph)},
          {"t1_c", num(f.t1_c)},
          {"t2_c", num(f.t2_c)},
          {"ta_c", num(f.ta_c)},
          {"rate_c_per_min", num(f.rate_c_per_min)},
          {"grad_c", num(f.grad_c)}};
}

json to_json(const RunComparison& c, bool with_series) {
  json steps = json::array();
  for (const auto& s : c.steps)
    steps.push_back({{"step", s.step},
                     {"phase", std::string(to_string(s.phase))},
                     {"start_s", s.start_s},
                     {"duration_s", s.duration_s},
                     {"stats", table(s.stats)}});
  json fails = json::array();
  for (const auto& f : c.failures) fails.push_back(to_json(f));
  json j = {{"run", c.run},
            {"verification", to_json(c.verification)},
            {"steps", steps},
            {"threshold_dph", c.threshold_dph},
            {"failures", fails},
            {"adequate", c.adequate()}};
  if (with_series) {
    std::vector<std::string> ph;
    for (Phase p : c.phase) ph.emplace_back(to_string(p));
    j["series"] = {{"time_s", series(c.time_s)},
                   {"measured_dph", series(c.measured_dph)},
                   {"predicted_dph", series(c.predicted_dph)},
                   {"residual_dph", series(c.residual_dph)},
                   {"residual_smooth_dph", series(c.residual_smooth_dph)},
                   {"t1_c", series(c.t1_c)},
                   {"t2_c", series(c.t2_c)},
                   {"ta_c", series(c.ta_c)},
                   {"phase", ph}};
  }
  return j;
}

json to_json(const Candidate& c) {
  json held = json::array();
  for (const auto& h : c.held_out) {
    json o = {{"run", h.run}, {"scored", h.scored}};
    if (h.scored) {
      o["rms_before"] = h.rms_before_dph;
      o["rms_after"] = h.rms_after_dph;
    } else {
      o["skipped"] = h.skipped;
    }
    held.push_back(o);
  }
  json j = {{"term", c.term},
            {"expr", c.expr},
            {"effect", c.effect},
            {"explanation", c.explanation},
            {"lag_s", c.lag_s},
            {"second_lag", c.second_lag},
            {"evaluated", c.evaluated},
            {"detected", c.detected}};
  if (!c.evaluated) {
    j["skipped"] = c.skipped;
    return j;
  }
  j.update(json{{"rms_before", c.rms_before_dph},
                {"rms_after", num(c.rms_after_dph)},
                {"fall", num(c.fall)},
                {"delta_bic", c.delta_bic},
                {"coef", c.coef},
                {"se", c.se_dph_per_unit},
                {"unit", c.unit},
                {"t", c.t},
                {"p_value", c.p_value},
                {"held_out", held},
                {"held_out_fall", c.held_out_fall},
                {"verdict", c.verdict},
                {"collinear_with", c.collinear_with}});
  if (!c.separate_by.empty()) j["separate_by"] = c.separate_by;
  return j;
}

json to_json(const RunCheck& c) {
  json fails = json::array();
  for (const auto& f : c.failures) fails.push_back(to_json(f));
  json j = {{"run", c.run},
            {"held_out", c.held_out},
            {"checked", c.checked},
            {"comp_std_dph", num(c.comp_std_dph)},
            {"noise_std_dph", num(c.noise_std_dph)},
            {"noise_factor", num(c.noise_factor)},
            {"noise_limit_factor", num(c.noise_limit_factor)},
            {"noise_floor", c.floor_note},
            {"acf_allowed", num(c.acf_allowed)},
            {"ljung_box_q", num(c.ljung_box_q)},
            {"ljung_box_p", num(c.ljung_box_p)},
            {"acf_rms", num(c.acf_rms)},
            {"failures", fails},
            {"reasons", c.reasons}};
  if (!c.error.empty()) j["error"] = c.error;
  return j;
}

json to_json(const Diagnosis& d) {
  json coefs = json::array();
  for (const auto& c : d.coefs) coefs.push_back({{"term", c.term}, {"coef", c.coef}, {"se", c.se_in_unit}, {"unit", c.unit}});
  json pairs = json::array();
  for (const auto& p : d.collinear_coefs) pairs.push_back({{"a", p.a}, {"b", p.b}, {"r", p.r}, {"why", p.why}});
  json ccf = json::array();
  for (const auto& c : d.ccf)
    ccf.push_back({{"term", c.term}, {"band", c.band}, {"peak_lag_s", c.peak_lag_s}, {"peak_r", c.peak_r}, {"outside", c.outside}, {"r", c.r}});
  json cands = json::array();
  for (const auto& c : d.candidates) cands.push_back(to_json(c));
  const Whiteness& w = d.whiteness;
  auto checks = [](const std::vector<RunCheck>& v) {
    json a = json::array();
    for (const auto& c : v) a.push_back(to_json(c));
    return a;
  };
  json jumps = json::array();
  for (const auto& j : d.jumps)
    jumps.push_back({{"run", j.run}, {"time_s", j.time_s}, {"size_dph", j.size_dph}, {"t", j.t}, {"message", j.message}});
  json steps = json::array();
  for (const auto& st : d.steps) {
    json ho = json::array();
    for (const auto& h : st.held_out) {
      json x = {{"run", h.run}, {"scored", h.scored}};
      if (h.scored) {
        x["rms_before"] = h.rms_before_dph;
        x["rms_after"] = h.rms_after_dph;
      } else {
        x["skipped"] = h.skipped;
      }
      ho.push_back(x);
    }
    steps.push_back({{"added", st.added},
                     {"expr", st.expr},
                     {"effect", st.effect},
                     {"library", st.library},
                     {"rms_before", st.rms_before_dph},
                     {"rms_after", st.rms_after_dph},
                     {"held_out", ho},
                     {"look_alikes", st.look_alikes}});
  }
  return {{"fit_run", d.fit_run},
          {"held_out_runs", d.held_out_runs},
          {"model", d.model_terms},
          {"method", d.method},
          {"base_refitted_on_other_run", d.base_refitted_on_other_run},
          {"rms_fit", d.rms_fit_dph},
          {"whiteness",
           {{"acf", w.acf},
            {"pacf", w.pacf},
            {"band", w.band},
            {"acf_outside", w.acf_outside},
            {"pacf_outside", w.pacf_outside},
            {"ljung_box_q", w.lb.q},
            {"ljung_box_p", w.lb.p_value},
            {"ljung_box_dof", w.lb.dof},
            {"white", w.white()}}},
          {"coefficients", coefs},
          {"coef_corr", d.coef_corr},
          {"collinear_coefficients", pairs},
          {"ccf", ccf},
          {"candidates", cands},
          {"adequate", d.adequate},
          {"reasons", d.reasons},
          {"checks", checks(d.checks)},
          {"jumps", jumps},
          {"time_drift", to_json(d.time_drift)},
          {"periodic", [&] {
             json a = json::array();
             for (const auto& p : d.periodic) a.push_back(to_json(p));
             return a;
           }()},
          {"search", d.search},
          {"search_space", d.search_space},
          {"steps", steps},
          {"final_terms", d.final_terms},
          {"final_checks", checks(d.final_checks)},
          {"outside_search", d.outside_search},
          {"residual_follows", d.residual_follows},
          {"rule", d.rule},
          {"summary", d.summary}};
}

json to_json(const TimeDrift& t) {
  json runs = json::array();
  for (const auto& r : t.runs) runs.push_back({{"run", r.run}, {"slope_dph_per_h", num(r.slope_dph_per_h)}, {"se_dph_per_h", num(r.se_dph_per_h)}});
  json ser = json::array();
  for (const auto& x : t.series)
    ser.push_back({{"run", x.run}, {"time_s", series(x.time_s)}, {"residual_dph", series(x.residual_dph)}, {"fitted_dph", series(x.fitted_dph)}});
  return {{"tested", t.tested},
          {"found", t.found},
          {"named", t.named},
          {"collinear", t.collinear},
          {"slope_dph_per_h", num(t.slope_dph_per_h)},
          {"se_dph_per_h", num(t.se_dph_per_h)},
          {"t", num(t.t)},
          {"consistency_p", num(t.consistency_p)},
          {"r_time_t1", num(t.r_time_t1)},
          {"thermal_term", t.thermal_term},
          {"runs", runs},
          {"series", ser},
          {"message", t.message}};
}

json to_json(const PeriodicDisturbance& p) {
  return {{"run", p.run},
          {"period_s", num(p.period_s)},
          {"amplitude_dph", num(p.amplitude_dph)},
          {"phase_rad", num(p.phase_rad)},
          {"power_ratio", num(p.power_ratio)},
          {"p_value", num(p.p_value)},
          {"frequencies", p.frequencies},
          {"thermal_period", p.thermal_period},
          {"rms_before_dph", num(p.rms_before_dph)},
          {"rms_after_dph", num(p.rms_after_dph)},
          {"spectrum", {{"period_s", series(p.spectrum_period_s)}, {"amplitude_dph", series(p.spectrum_amp_dph)}, {"noise_amplitude_dph", series(p.noise_amp_dph)}}},
          {"message", p.message}};
}

json to_json(const Lineage& l) {
  json steps = json::array();
  for (const auto& s : l.steps) {
    json per = json::array();
    for (std::size_t i = 0; i < s.comp_std_dph.size(); ++i) {
      json o = {{"run", l.runs[i]}, {"comp_std_dph", num(s.comp_std_dph[i])}};
      if (!s.errors[i].empty()) o["error"] = s.errors[i];
      per.push_back(o);
    }
    steps.push_back({{"terms", s.terms}, {"note", s.note}, {"created_at", s.created_at}, {"fitted_on", s.fitted_on}, {"runs", per}});
  }
  return {{"runs", l.runs}, {"lineage", steps}};
}

json to_json(const Qualification& q) {
  json sens = json::array();
  for (const auto& s : q.sensitivities) sens.push_back({{"term", s.term}, {"unit", s.unit}, {"coef", s.coef}, {"se", s.se_in_unit}});
  json runs = json::array();
  for (const auto& r : q.runs)
    runs.push_back({{"run", r.run},
                    {"held_out", r.held_out},
                    {"meas_std_dph", r.meas_std_dph},
                    {"comp_std_dph", r.comp_std_dph},
                    {"ratio", r.ratio},
                    {"hysteresis_dph", num(r.hysteresis_dph)},
                    {"hysteresis_comp_dph", num(r.hysteresis_comp_dph)},
                    {"peak_ramp_excursion_dph", r.peak_ramp_excursion_dph},
                    {"verdict", std::string(to_string(r.verdict))},
                    {"reasons", r.reasons},
                    {"pass", r.pass}});
  return {{"standard", "IEEE Std 952-1997 (thermal sensitivity of bias)"},
          {"mu0_dph", q.mu0_dph},
          {"mu0_se_dph", q.mu0_se_dph},
          {"sensitivities", sens},
          {"runs", runs},
          {"threshold", q.threshold},
          {"verdict", q.pass ? "pass" : q.marginal ? "marginal" : "fail"},
          {"pass", q.pass}};
}

}  // namespace fogbench::model::workbench
