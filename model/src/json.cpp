// JSON form of models and verifications (format "fogbench.model", version 1).
#include "fogbench/model/json.hpp"

#include <algorithm>
#include <cmath>

namespace fogbench::model {
namespace {

using nlohmann::json;

struct Reader {
  const json& j;
  std::string path;
  std::string err;

  const json* get(const char* key, bool required = true) {
    if (!err.empty()) return nullptr;
    if (!j.is_object()) {
      err = (path.empty() ? std::string("model") : path) + ": expected an object";
      return nullptr;
    }
    auto it = j.find(key);
    if (it == j.end()) {
      if (required) err = field(key) + ": missing";
      return nullptr;
    }
    return &*it;
  }
  std::string field(const char* key) const { return path.empty() ? key : path + "." + key; }
  double number(const char* key, double dflt = 0.0, bool required = true) {
    const json* v = get(key, required);
    if (!v) return dflt;
    if (!v->is_number()) {
      err = field(key) + ": expected a number";
      return dflt;
    }
    return v->get<double>();
  }
  long long integer(const char* key, long long dflt = 0, bool required = true) {
    const json* v = get(key, required);
    if (!v) return dflt;
    if (!v->is_number_integer()) {
      err = field(key) + ": expected an integer";
      return dflt;
    }
    return v->get<long long>();
  }
  std::string string(const char* key, std::string dflt = {}, bool required = true) {
    const json* v = get(key, required);
    if (!v) return dflt;
    if (!v->is_string()) {
      err = field(key) + ": expected a string";
      return dflt;
    }
    return v->get<std::string>();
  }
  bool boolean(const char* key, bool dflt = false, bool required = true) {
    const json* v = get(key, required);
    if (!v) return dflt;
    if (!v->is_boolean()) {
      err = field(key) + ": expected true or false";
      return dflt;
    }
    return v->get<bool>();
  }
};

}  // namespace

json to_json(const Model& m) {
  json terms = json::array();
  for (const auto& t : m.terms) {
    terms.push_back({{"term", t.name()},
                     {"lag_s", t.term.lag.seconds},
                     {"lag_auto", t.term.lag.automatic},
                     {"coef", t.coef},
                     {"se", t.se_dph_per_unit},
                     {"unit", coef_unit(*t.term.expr)}});
  }
  json j = {
      {"format", "fogbench.model"},
      {"format_version", kModelFormatVersion},
      {"method", std::string(to_string(m.method))},
      {"terms", terms},
      {"shared_lag", m.shared_lag},
      {"mu0", m.mu0_dph},
      {"mu0_se", m.mu0_se_dph},
      {"ar", m.ar},
      {"sigma_a", m.sigma_a_dph},
      {"tref_c", m.tref_c},
      {"options", {{"max_lag_s", m.max_lag_s}, {"smooth_s", m.smooth_s}, {"hold_s", m.hold_s}}},
      {"fit",
       {{"n_used", m.fit.n_used},
        {"n_outliers", m.fit.n_outliers},
        {"n_flagged", m.fit.n_flagged},
        {"n_hold", m.fit.n_hold},
        {"rss", m.fit.rss},
        {"bic", m.fit.bic},
        {"trend_r2", m.fit.trend_r2},
        {"stationary", m.fit.stationary},
        {"ljung_box_q", m.fit.ljung_box_q},
        {"ljung_box_p", m.fit.ljung_box_p},
        {"iterations", m.fit.iterations},
        {"converged", m.fit.converged},
        {"coef_corr", m.fit.coef_corr}}},
      {"fitted_on",
       {{"name", m.fitted_on.name},
        {"n_samples", m.fitted_on.n_samples},
        {"duration_s", m.fitted_on.duration_s},
        {"t1_min_c", m.fitted_on.t1_min_c},
        {"t1_max_c", m.fitted_on.t1_max_c},
        {"fingerprint", m.fitted_on.fingerprint}}},
      {"created_at", m.created_at},
      {"note", m.note},
  };
  if (!m.fit.lag_note.empty()) j["fit"]["lag_note"] = m.fit.lag_note;
  if (m.axis) j["axis"] = std::string(to_string(*m.axis));  // absent for a one-axis run's model
  j["parent"] = m.parent ? to_json(*m.parent) : json(nullptr);
  return j;
}

std::expected<Model, std::string> model_from_json(const json& j) {
  Model m;
  Reader r{j, "", ""};
  if (r.string("format") != "fogbench.model" && r.err.empty()) return std::unexpected(std::string("format: expected \"fogbench.model\""));
  const long long ver = r.integer("format_version");
  if (r.err.empty() && ver != kModelFormatVersion)
    return std::unexpected("format_version: this fogbench reads version " + std::to_string(kModelFormatVersion) + ", the file is version " + std::to_string(ver));
  const std::string method = r.string("method");
  if (r.err.empty()) {
    auto mm = method_from_string(method);
    if (!mm) return std::unexpected("method: expected \"paper\" or \"joint\", found \"" + method + "\"");
    m.method = *mm;
  }
  m.shared_lag = r.boolean("shared_lag", false, false);
  m.mu0_dph = r.number("mu0");
  m.mu0_se_dph = r.number("mu0_se", 0.0, false);
  m.sigma_a_dph = r.number("sigma_a");
  m.tref_c = r.number("tref_c", 20.0, false);
  m.created_at = r.string("created_at", "", false);
  m.note = r.string("note", "", false);
  if (!r.err.empty()) return std::unexpected(r.err);
  if (const json* a = r.get("axis", false)) {
    const auto axis = a->is_string() ? axis_from_string(a->get<std::string>()) : std::nullopt;
    if (!axis) return std::unexpected("axis: expected \"x\", \"y\" or \"z\", found " + a->dump());
    m.axis = *axis;
  }
  if (const json* ar = r.get("ar")) {
    if (!ar->is_array()) return std::unexpected(std::string("ar: expected an array of numbers"));
    for (std::size_t i = 0; i < ar->size(); ++i) {
      if (!(*ar)[i].is_number()) return std::unexpected("ar[" + std::to_string(i) + "]: expected a number");
      m.ar.push_back((*ar)[i].get<double>());
    }
  }
  if (!r.err.empty()) return std::unexpected(r.err);
  const json* terms = r.get("terms");
  if (!terms) return std::unexpected(r.err);
  if (!terms->is_array()) return std::unexpected(std::string("terms: expected an array"));
  for (std::size_t i = 0; i < terms->size(); ++i) {
    Reader tr{(*terms)[i], "terms[" + std::to_string(i) + "]", ""};
    const std::string spec = tr.string("term");
    const long long lag = tr.integer("lag_s");
    const bool automatic = tr.boolean("lag_auto", false, false);
    FittedTerm ft;
    ft.coef = tr.number("coef");
    ft.se_dph_per_unit = tr.number("se", 0.0, false);
    if (!tr.err.empty()) return std::unexpected(tr.err);
    auto t = parse_term(spec);
    if (!t) return std::unexpected(tr.path + ".term: " + t.error().pretty());
    if (lag < 0 || lag > 86400) return std::unexpected(tr.path + ".lag_s: expected 0..86400 s, found " + std::to_string(lag));
    ft.term = *t;
    ft.term.coef = 1.0;
    ft.term.coef_given = false;
    ft.term.lag = Lag{automatic, static_cast<int>(lag)};
    m.terms.push_back(std::move(ft));
  }
  if (const json* o = r.get("options", false)) {
    Reader orr{*o, "options", ""};
    m.max_lag_s = static_cast<int>(orr.integer("max_lag_s", 600, false));
    m.smooth_s = static_cast<int>(orr.integer("smooth_s", 61, false));
    m.hold_s = static_cast<int>(orr.integer("hold_s", 600, false));
    if (!orr.err.empty()) return std::unexpected(orr.err);
  }
  if (const json* f = r.get("fit", false)) {
    Reader fr{*f, "fit", ""};
    m.fit.n_used = static_cast<std::size_t>(fr.integer("n_used", 0, false));
    m.fit.n_outliers = static_cast<std::size_t>(fr.integer("n_outliers", 0, false));
    m.fit.n_flagged = static_cast<std::size_t>(fr.integer("n_flagged", 0, false));
    m.fit.n_hold = static_cast<std::size_t>(fr.integer("n_hold", 0, false));
    m.fit.rss = fr.number("rss", 0.0, false);
    m.fit.bic = fr.number("bic", 0.0, false);
    m.fit.trend_r2 = fr.number("trend_r2", 0.0, false);
    m.fit.stationary = fr.boolean("stationary", true, false);
    m.fit.ljung_box_q = fr.number("ljung_box_q", 0.0, false);
    m.fit.ljung_box_p = fr.number("ljung_box_p", 1.0, false);
    m.fit.iterations = static_cast<int>(fr.integer("iterations", 0, false));
    m.fit.converged = fr.boolean("converged", true, false);
    m.fit.lag_note = fr.string("lag_note", "", false);
    if (!fr.err.empty()) return std::unexpected(fr.err);
    // The file keeps iterations and converged only (its format is unchanged): the summary is
    // rebuilt from them.
    m.fit.summary.method = m.method;
    m.fit.summary.iterations = m.fit.iterations;
    m.fit.summary.termination = m.fit.converged ? FitTermination::converged : FitTermination::no_convergence;
    m.fit.summary.stage = "done";
    if (auto it = f->find("coef_corr"); it != f->end()) {
      try {
        m.fit.coef_corr = it->get<std::vector<std::vector<double>>>();
      } catch (const json::exception&) {
        return std::unexpected(std::string("fit.coef_corr: expected a matrix of numbers"));
      }
    }
  }
  if (const json* f = r.get("fitted_on", false)) {
    Reader fr{*f, "fitted_on", ""};
    m.fitted_on.name = fr.string("name", "", false);
    m.fitted_on.n_samples = static_cast<std::size_t>(fr.integer("n_samples", 0, false));
    m.fitted_on.duration_s = fr.number("duration_s", 0.0, false);
    m.fitted_on.t1_min_c = fr.number("t1_min_c", 0.0, false);
    m.fitted_on.t1_max_c = fr.number("t1_max_c", 0.0, false);
    m.fitted_on.fingerprint = fr.string("fingerprint", "", false);
    if (!fr.err.empty()) return std::unexpected(fr.err);
  }
  if (auto it = j.find("parent"); it != j.end() && !it->is_null()) {
    auto parent = model_from_json(*it);
    if (!parent) return std::unexpected("parent." + parent.error());
    m.parent = std::make_shared<const Model>(std::move(*parent));
  }
  return m;
}

std::expected<Model, std::string> model_from_text(std::string_view text) {
  json j;
  try {
    j = json::parse(text.begin(), text.end());
  } catch (const json::parse_error& e) {
    // Where it broke, as an editor counts: line and column of the byte the parser stopped at
    // (a truncated file stops at its end).
    const std::size_t stop = std::min<std::size_t>(e.byte == 0 ? 0 : e.byte - 1, text.size());
    std::size_t line = 1, column = 1;
    for (std::size_t i = 0; i < stop; ++i) {
      if (text[i] == '\n') {
        ++line;
        column = 1;
      } else {
        ++column;
      }
    }
    std::string what = e.what();
    if (const auto p = what.find(": "); p != std::string::npos) what = what.substr(p + 2);
    return std::unexpected("not valid JSON at line " + std::to_string(line) + ", column " + std::to_string(column) + ": " + what);
  }
  return model_from_json(j);
}

json to_json(const FitSummary& s) {
  return {{"method", std::string(to_string(s.method))},
          {"termination", std::string(to_string(s.termination))},
          {"iterations", s.iterations},
          {"last_change", s.last_change},
          {"stage", s.stage},
          {"why", s.why},
          {"brief", s.brief()}};
}

json to_json(const Table1& t) {
  return {{"n", t.n},           {"est_mean", t.est_mean}, {"meas_mean", t.meas_mean}, {"est_std", t.est_std},
          {"meas_std", t.meas_std}, {"comp_std", t.comp_std}, {"ratio", t.ratio}};
}

json to_json(const NoiseFloor& f) {
  return {{"measured", f.measured()},
          {"white_dph", std::sqrt(f.white_var_dph2)},
          {"bias_instability_dph", f.bias_instability_dph},
          {"rrw_dph_per_sqrt_h", f.rrw_dph_per_sqrt_h},
          // When no walk is seen beside flicker: the largest the holds cannot exclude (0: none).
          {"rrw_not_excluded_dph_per_sqrt_h", f.rrw_bound_dph_per_sqrt_h},
          {"hold_samples", f.hold_samples},
          {"longest_tau_s", f.longest_tau_s},
          {"note", f.note}};
}

json to_json(const Verification& v) {
  json j = to_json(v.run);
  json phases = json::array();
  for (const auto& p : v.phases) {
    json pj = to_json(p.stats);
    pj["phase"] = std::string(to_string(p.phase));
    phases.push_back(pj);
  }
  j["phases"] = phases;
  j["n_outliers"] = v.n_outliers;
  j["n_flagged"] = v.n_flagged;
  j["threshold"] = v.threshold;
  j["pass"] = v.pass;
  j["verdict"] = std::string(to_string(v.verdict));
  j["ratio_pass"] = v.ratio_pass;
  j["noise_test"] = v.noise_test;
  j["noise_std"] = v.noise_std;
  j["noise_factor"] = std::isfinite(v.noise_factor) ? json(v.noise_factor) : json(nullptr);
  j["noise_limit_factor"] = v.noise_limit_factor;
  j["threshold_dph"] = v.threshold_dph;
  j["noise_floor"] = to_json(v.floor);
  j["longest_fail_s"] = v.longest_fail_s;
  j["reasons"] = v.reasons;
  return j;
}

}  // namespace fogbench::model
