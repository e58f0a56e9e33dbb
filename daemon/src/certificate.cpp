// A certificate per serial: built from the store (certificate.hpp), hashed in its canonical
// form, stored once per content.
#include "fogbench/daemon/certificate.hpp"

#include <cmath>
#include <set>

#include "fogbench/daemon/run_identity.hpp"
#include "fogbench/model/allan.hpp"
#include "fogbench/model/json.hpp"
#include "fogbench/model/model.hpp"
#include "fogbench/model/scale_factor.hpp"
#include "fogbench/profiles/profile.hpp"
#include "fogbench/protocol/build_info.hpp"
#include "fogbench/signing/certificate.hpp"
#include "fogbench/storage/models.hpp"
#include "fogbench/storage/run_data.hpp"
#include "verdict.hpp"

namespace fogbench::daemon::certificate {

using nlohmann::json;
namespace allan = model::allan;

namespace {

json num_or_null(double v) { return std::isfinite(v) ? json(v) : json(nullptr); }

json estimate_json(const std::optional<allan::NoiseEstimate>& e, const std::string& note) {
  json j = json::object();
  if (e)
    j = {{"value", num_or_null(e->value)}, {"ci_low", num_or_null(e->ci_low)}, {"ci_high", num_or_null(e->ci_high)},
         {"from_tau_s", e->from_tau_s}, {"to_tau_s", e->to_tau_s},
         // The interval's evidence: sigma^2's equivalent degrees of freedom at that tau and the
         // term's share of sigma^2 there (0..1), as fogctl allan prints them.
         {"edf", num_or_null(e->edf)}, {"share", num_or_null(e->share)}};
  else
    j = {{"value", nullptr}};
  j["note"] = note;
  return j;
}

// The Allan figures of the model's compensated output on a stored run's unit: the longest
// even, unflagged stretch (every phase: compensation is meant to remove the ramps' drift).
json allan_of(storage::Store& store, const model::Model& m, std::int64_t run_id, int unit) {
  auto data = store.export_run(run_id, unit);
  if (!data) return {{"error", data.error().message}};
  storage::bridge_missing(*data);
  auto mu = model::predict(m, *data);
  if (!mu) return {{"error", mu.error().message}};
  model::RunData comp = *data;
  for (std::size_t i = 0; i < comp.size(); ++i) comp.gyro_dph[i] -= (*mu)[i];
  std::optional<allan::Stretch> longest;
  for (const auto& s : allan::even_stretches(comp, 7, true))
    if (!longest || s.end - s.begin > longest->end - longest->begin) longest = s;
  if (!longest) return {{"error", "no stretch of 7 or more evenly spaced, unflagged samples"}};
  std::vector<double> rate(comp.gyro_dph.begin() + static_cast<std::ptrdiff_t>(longest->begin),
                           comp.gyro_dph.begin() + static_cast<std::ptrdiff_t>(longest->end));
  auto curve = allan::overlapping_adev(rate, longest->tau0_s, allan::octave_cluster_sizes(rate.size()));
  if (!curve) return {{"error", curve.error()}};
  const auto t = allan::noise_terms(*curve);
  return {{"series", "compensated"},
          {"from_s", comp.time_s[longest->begin]},
          {"to_s", comp.time_s[longest->end - 1]},
          {"samples", rate.size()},
          {"arw_deg_per_sqrt_h", estimate_json(t.arw_deg_per_sqrt_h, t.arw_note)},
          {"bias_instability_dph", estimate_json(t.bias_instability_dph, t.bias_instability_note)},
          {"rrw_dph_per_sqrt_h", estimate_json(t.rrw_dph_per_sqrt_h, t.rrw_note)}};
}

json coefficient_json(const model::sf::Coefficient& c) {
  if (c.value) return {{"value", num_or_null(*c.value)}, {"sigma", num_or_null(c.se)}};
  return {{"value", nullptr}, {"note", c.not_identified}};
}

// The scale factor over temperature (model::sf::fit, docs/scale-factor.md) of the serial's unit
// in a run whose profile (as run) has rate steps; nullopt for a run without rate steps (then
// the certificate has no scale-factor entry for it). A fit that fails gives its reason.
std::optional<json> scale_factor_of(storage::Store& store, const storage::RunRecord& run, const std::string& serial) {
  auto prof = profiles::parse_profile(run.profile_text, run.profile_name + ".profile");
  if (!prof || prof->rate_steps.empty()) return std::nullopt;
  json j = {{"run_id", run.id}};
  int unit = -1;
  for (const auto& u : run.units)
    if (u.serial == serial) unit = u.unit_index;
  if (unit < 0) return std::nullopt;
  auto data = store.export_run(run.id, unit);
  if (!data) {
    j["error"] = data.error().message;
    return j;
  }
  auto rec = model::sf::rate_record(*data);
  if (!rec) {
    j["error"] = rec.error();
    return j;
  }
  const model::sf::Options options;
  auto f = model::sf::fit(*rec, options);
  if (!f) {
    j["error"] = f.error();
    return j;
  }
  json plateaus = json::array();
  for (const auto& p : f->plateaus)
    plateaus.push_back({{"plateau", p.id}, {"coil_c", num_or_null(p.coil_c)}, {"scale_factor", num_or_null(p.scale_factor)},
                        {"sigma", num_or_null(p.scale_factor_se)}, {"bias_dph", num_or_null(p.bias_dph)},
                        {"nonlinearity_ppm", num_or_null(p.nonlinearity_ppm)}, {"asymmetry_ppm", num_or_null(p.asymmetry_ppm)}});
  j["settle_s"] = options.settle_s;
  j["t0_c"] = options.t0_c;
  j["sf0"] = num_or_null(f->sf0);
  j["tc_ppm_per_c"] = coefficient_json(f->tc_ppm_per_c);
  j["temp_rate_ppm_per_c_per_min"] = coefficient_json(f->temp_rate_ppm_per_c_per_min);
  j["model_form"] = {{"sf0", num_or_null(f->model_sf0)}, {"k1_ppm_per_c", coefficient_json(f->k1_ppm_per_c)},
                     {"k2_ppm_per_c2", coefficient_json(f->k2_ppm_per_c2)}, {"rms_ppm", num_or_null(f->model_rms_ppm)}};
  j["plateaus"] = plateaus;
  return j;
}

ApiResult<json> run_json(storage::Store& store, std::int64_t run_id, const std::string& role) {
  auto d = store.get_run(run_id);
  if (!d) return std::unexpected(from_store(d.error()));
  auto id = store.get_run_identity(run_id);
  if (!id) return std::unexpected(from_store(id.error()));
  // Each unit of the identity with its lot (null: none given), for traceability (issue 24).
  json identity = identity_json(*id);
  if (identity.is_object())
    for (auto& u : identity["units"]) {
      u["lot"] = nullptr;
      for (const auto& ru : d->run.units)
        if (u["unit"] == ru.unit_index && ru.lot) u["lot"] = *ru.lot;
    }
  return json{{"id", run_id},
              {"role", role},
              {"profile", d->run.profile_name},
              {"purpose", std::string(storage::to_string(d->run.purpose))},
              {"state", std::string(storage::to_string(d->run.state))},
              {"started_at", d->run.started_at ? json(*d->run.started_at) : json(nullptr)},
              {"ended_at", d->run.ended_at ? json(*d->run.ended_at) : json(nullptr)},
              {"identity", identity}};
}

}  // namespace

// The verdicts' limits are their own, stored with them: the configuration of today is not read.
ApiResult<json> build(storage::Store& store, const AnalysisConfig& /*config*/, const std::string& station_id,
                      const std::string& serial) {
  auto rec = store.current_model(serial);
  if (!rec) return std::unexpected(from_store(rec.error()));
  if (!*rec) return api_error(ErrorCode::not_found, "serial " + serial + ": no model, so no certificate");
  const storage::ModelRecord& mr = **rec;
  auto m = model::model_from_text(mr.model_json);
  if (!m) return api_error(ErrorCode::internal, "serial " + serial + ": model " + std::to_string(mr.id) + " unreadable: " + m.error());

  json coefficients = json::array();
  coefficients.push_back({{"term", "mu0"}, {"value", num_or_null(m->mu0_dph)}, {"sigma", num_or_null(m->mu0_se_dph)},
                          {"unit", "deg/h"}, {"lag_s", 0}});
  const json mj = json::parse(mr.model_json);
  for (const auto& t : mj.value("terms", json::array()))
    coefficients.push_back({{"term", t.value("term", "")}, {"value", t.contains("coef") ? t["coef"] : json(nullptr)},
                            {"sigma", t.contains("se") ? t["se"] : json(nullptr)}, {"unit", t.value("unit", "")},
                            {"lag_s", t.contains("lag_s") ? t["lag_s"] : json(nullptr)}});

  json runs = json::array();
  std::set<std::int64_t> listed;
  if (mr.run_id) {
    auto r = run_json(store, *mr.run_id, "fit");
    if (!r) return std::unexpected(r.error());
    runs.push_back(*r);
    listed.insert(*mr.run_id);
  }
  // Every verification of this model: the serial's runs, newest first from the store, taken oldest first.
  storage::RunFilter f;
  f.serial = serial;
  f.limit = 10000;
  auto all = store.list_runs(f);
  if (!all) return std::unexpected(from_store(all.error()));
  // The evidence: every verification of this model with its checks (what was measured against
  // which limit). The verdict is not recomputed from them: it is the serial's one verdict,
  // decided once by its rule (verdict.hpp), read back below.
  json verifications = json::array();
  json allans = json::array();
  for (auto it = all->rbegin(); it != all->rend(); ++it) {
    auto vs = store.list_verifications(it->id);
    if (!vs) return std::unexpected(from_store(vs.error()));
    for (const auto& v : *vs) {
      if (v.model_id != mr.id) continue;
      if (v.unit_index < 0 || v.unit_index >= static_cast<int>(it->units.size()) ||
          it->units[static_cast<std::size_t>(v.unit_index)].serial != serial)
        continue;
      const json res = json::parse(v.result_json, nullptr, false);
      if (!res.is_object()) continue;
      verifications.push_back(
          {{"run_id", it->id},
           {"verification_id", v.id},
           {"checks", verdict::analysis_checks(res)},
           {"table1",
            {{"raw_std_dph", res.value("meas_std", json(nullptr))},
             {"comp_std_dph", res.value("comp_std", json(nullptr))},
             {"n", res.value("n", json(nullptr))}}}});
      json a = allan_of(store, *m, it->id, v.unit_index);
      a["run_id"] = it->id;
      allans.push_back(std::move(a));
      if (!listed.contains(it->id)) {
        auto r = run_json(store, it->id, "verify");
        if (!r) return std::unexpected(r.error());
        runs.push_back(*r);
        listed.insert(it->id);
      }
    }
  }
  // The scale factor over temperature of each listed run that had rate steps (issue 29, point 2).
  json scale_factors = json::array();
  for (const auto& r : runs) {
    auto d = store.get_run(r["id"].get<std::int64_t>());
    if (!d) return std::unexpected(from_store(d.error()));
    if (auto sf = scale_factor_of(store, d->run, serial)) {
      (*sf)["role"] = r["role"];
      scale_factors.push_back(std::move(*sf));
    }
  }
  auto latest = store.latest_verdict(serial);
  if (!latest) return std::unexpected(from_store(latest.error()));
  const verdict::Certified decided = verdict::certified(*latest, mr.id);
  const auto& info = protocol::build_info();
  json cert = json{{"format", "fogbench.certificate"},
              {"format_version", signing::kCertificateFormatVersion},
              {"serial", serial},
              {"station_id", station_id},
              {"model",
               {{"id", mr.id}, {"version", mr.version}, {"method", mr.method}, {"terms", mr.terms},
                {"created_at", mr.created_at}, {"fitted_on_run", mr.run_id ? json(*mr.run_id) : json(nullptr)},
                {"sigma_a_dph", num_or_null(m->sigma_a_dph)}, {"coefficients", coefficients}}},
              {"verdict", decided.verdict},
              {"qualification", decided.qualification},
              {"verifications", verifications},
              {"runs", runs},
              {"allan", allans},
              {"software", {{"version", std::string(info.version)}, {"git_hash", std::string(info.git_hash)},
                            {"git_describe", std::string(info.git_describe)}}}};
  // Only when a run had rate steps: a certificate without them is what it was before.
  if (!scale_factors.empty()) cert["scale_factor"] = scale_factors;
  // A three-axis unit (a y model on file): each axis' current model and what the serial's
  // decision says of that axis (its qualification's `axes`), signed with the rest; a one-axis
  // unit's certificate has no `axes` and is what it was before.
  auto y_model = store.current_model(serial, "y");
  if (!y_model) return std::unexpected(from_store(y_model.error()));
  if (*y_model) {
    json axes = json::array();
    for (const char* axis : {"x", "y", "z"}) {
      std::optional<storage::ModelRecord> am;
      if (std::string_view(axis) == "x") {
        am = mr;
      } else {
        auto r = store.current_model(serial, axis);
        if (!r) return std::unexpected(from_store(r.error()));
        am = *r;
      }
      json e = {{"axis", axis}, {"model", nullptr}, {"verdict", "not verified"}, {"decided_on_model", nullptr},
                {"reasons", json::array()}};
      if (am)
        e["model"] = {{"id", am->id}, {"version", am->version}, {"method", am->method}, {"terms", am->terms},
                      {"fitted_on_run", am->run_id ? json(*am->run_id) : json(nullptr)}};
      const json& q = decided.qualification;
      if (q.is_object() && q.contains("axes") && q["axes"].is_array())
        for (const auto& d : q["axes"])
          if (d.is_object() && d.value("axis", "") == axis) {
            e["verdict"] = d.value("verdict", json("not verified"));
            e["decided_on_model"] = d.value("model_id", json(nullptr));
            e["reasons"] = d.contains("reasons") && d["reasons"].is_array() ? d["reasons"] : json::array();
          }
      axes.push_back(std::move(e));
    }
    cert["axes"] = axes;
  }
  return cert;
}

std::string hash_of(const json& cert) { return signing::content_sha256(cert); }

ApiResult<std::pair<json, bool>> issue(storage::Store& writer, const json& body, const std::string& issued_at,
                                       const signing::SigningKey& key) {
  const std::string serial = body.value("serial", "");
  auto stored = writer.list_certificates(serial);
  if (!stored) return std::unexpected(from_store(stored.error()));
  if (!stored->empty()) {
    json last = json::parse(stored->back().json, nullptr, false);
    // The same facts signed by this key: handed out again. One unsigned (before issue 24) or
    // signed by an older key (a rotation) is issued anew.
    if (last.is_object() && last.contains("signature") && last.contains("signed_by") && last["signed_by"].is_object() &&
        last["signed_by"].value("key_id", "") == key.key_id()) {
      json same = last;
      for (const char* k : {"sha256", "issued_at", "signature", "signed_by", "format_version"}) same.erase(k);
      json fresh = body;
      fresh.erase("format_version");
      if (same == fresh) return std::pair{last, false};
    }
  }
  json cert = body;
  cert["issued_at"] = issued_at;
  if (auto ok = signing::sign_certificate(cert, key, body.value("station_id", "")); !ok)
    return api_error(ErrorCode::internal, "serial " + serial + ": cannot sign the certificate: " + ok.error());
  storage::NewCertificate nc;
  nc.serial = serial;
  nc.model_id = body["model"]["id"].get<std::int64_t>();
  nc.model_version = body["model"]["version"].get<int>();
  nc.sha256 = cert["sha256"].get<std::string>();
  nc.json = cert.dump();
  auto id = writer.put_certificate(nc);
  if (!id) return std::unexpected(from_store(id.error()));
  return std::pair{cert, true};
}

}  // namespace fogbench::daemon::certificate
