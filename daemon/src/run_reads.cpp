// The run reads of the socket protocol (run_reads.hpp): how a stored run, its models, samples
// and verdicts are shown in replies. Split out of handler.cpp, which keeps the command table,
// request checking and dispatch.
#include "run_reads.hpp"

#include <cmath>
#include <optional>

#include "fogbench/daemon/run_identity.hpp"
#include "fogbench/protocol/protocol.hpp"
#include "fogbench/model/json.hpp"
#include "verdict.hpp"

namespace fogbench::daemon {

using nlohmann::json;

json run_json(const storage::RunRecord& r) {
  json units = json::array(), lots = json::array(), slots = json::array();
  for (const auto& u : r.units) {
    units.push_back(u.serial);
    lots.push_back(u.lot ? json(*u.lot) : json(nullptr));  // same positions; null: no lot given
    slots.push_back(u.slot ? json(*u.slot) : json(nullptr));  // null: stored before bench slots
  }
  return {{"id", r.id}, {"created_at", r.created_at}, {"profile", r.profile_name},
          {"purpose", std::string(storage::to_string(r.purpose))},
          {"state", std::string(storage::to_string(r.state))}, {"reason", r.state_reason},
          {"started_at", r.started_at ? json(*r.started_at) : json(nullptr)},
          {"ended_at", r.ended_at ? json(*r.ended_at) : json(nullptr)},
          {"time_scale", r.time_scale}, {"units", units}, {"lots", lots},
          {"slots", slots},
          // Store::prune deleted its samples (fogctl store prune): when, and how many.
          {"pruned_at", r.pruned_at ? json(*r.pruned_at) : json(nullptr)},
          {"pruned_samples", r.pruned_samples}};
}

json parse_or_string(const std::string& text) {
  json j = json::parse(text, nullptr, false);
  return j.is_discarded() ? json(text) : j;
}

json model_json(const storage::ModelRecord& m) {
  json j = {{"id", m.id}, {"serial", m.serial}, {"version", m.version},
            {"run_id", m.run_id ? json(*m.run_id) : json(nullptr)},
            {"parent_id", m.parent_id ? json(*m.parent_id) : json(nullptr)},
            {"created_at", m.created_at}, {"method", m.method}, {"terms", m.terms},
            {"model", parse_or_string(m.model_json)}};
  if (!m.axis.empty()) j["axis"] = m.axis;  // a three-axis unit's model
  return j;
}

json sample_json(const storage::SampleRow& r, int axes) {
  auto finite = [](double v) { return std::isfinite(v) ? std::optional(v) : std::nullopt; };
  protocol::Sample s;
  s.t_s = r.t_s;
  s.wall_time = finite(r.wall_time);
  s.setpoint_c = finite(r.setpoint_c);
  s.chamber_c = finite(r.chamber_c);
  s.gyro_dph = finite(r.gyro_dph);
  s.frames = r.frames;
  s.t1_c = finite(r.t1_c);
  s.t2_c = finite(r.t2_c);
  s.phase = std::string(model::to_string(r.phase));
  s.step = r.step;
  s.flags = r.flags;
  s.since_power_on_s = finite(r.since_power_on_s);
  s.compensated_dph = finite(r.compensated_dph);
  s.rate_in_dps = finite(r.rate_in_dps);
  s.three_axis = axes == 3;
  if (s.three_axis) {
    s.gyro_y_dph = finite(r.gyro_y_dph);
    s.gyro_z_dph = finite(r.gyro_z_dph);
    s.axis_thermistors = std::isfinite(r.t1_y_c) || std::isfinite(r.t2_y_c) || std::isfinite(r.t1_z_c) || std::isfinite(r.t2_z_c);
    if (s.axis_thermistors) {
      s.t1_y_c = finite(r.t1_y_c);
      s.t2_y_c = finite(r.t2_y_c);
      s.t1_z_c = finite(r.t1_z_c);
      s.t2_z_c = finite(r.t2_z_c);
    }
  }
  return protocol::to_json(s);
}

// `unit` is an index into the run's units or a serial; absent means the first unit.
ApiResult<int> resolve_unit(storage::Store& store, std::int64_t run_id, const json& req) {
  auto u = resolve_run_unit(store, run_id, req);
  if (!u) return std::unexpected(u.error());
  return u->unit_index;
}

ApiResult<storage::RunUnit> resolve_run_unit(storage::Store& store, std::int64_t run_id, const json& req) {
  auto run = store.get_run(run_id);
  if (!run) return std::unexpected(from_store(run.error()));
  const auto& units = run->run.units;
  if (!req.contains("unit") || req["unit"].is_null()) {
    if (units.empty()) return api_error(ErrorCode::not_found, "run " + std::to_string(run_id) + " has no units");
    return units[0];
  }
  const json& u = req["unit"];
  if (u.is_number_integer()) {
    const auto i = u.get<std::int64_t>();
    if (i < 0 || i >= static_cast<std::int64_t>(units.size()))
      return api_error(ErrorCode::not_found, "run " + std::to_string(run_id) + " has no unit " + std::to_string(i));
    return units[static_cast<std::size_t>(i)];
  }
  if (u.is_string()) {
    for (const auto& ru : units)
      if (ru.serial == u.get<std::string>()) return ru;
    return api_error(ErrorCode::not_found, "run " + std::to_string(run_id) + " has no unit " + u.get<std::string>());
  }
  return api_error(ErrorCode::bad_request, "unit: expected an index or a serial");
}


// run.get through `store` (the worker's read connection); `end` and `live_quality` are what the
// station knows and the store may not yet (taken on the loop before the read was submitted).
ApiResult<json> run_get(storage::Store& store, std::int64_t run_id, const json& end, const json& live_quality) {
  auto d = store.get_run(run_id);
  if (!d) return std::unexpected(from_store(d.error()));
  json r = run_json(d->run);
  // An end the store could not take yet (a full disk) is the run's state all the same.
  if (!end.is_null()) {
    r["state"] = end["state"];
    r["reason"] = end["reason"];
    r["recorded"] = false;
  }
  json events = json::array();
  // Data quality per unit: live while the run is active, else the `quality` note stored when
  // it ended (null for a run without one: interrupted by a crash, imported, older).
  json quality = live_quality;
  const bool live = !quality.is_null();
  for (const auto& e : d->events) {
    json detail = parse_or_string(e.detail_json);
    if (!live && e.kind == storage::EventKind::note && detail.is_object() && detail.contains("quality"))
      quality = detail["quality"];
    events.push_back({{"id", e.id}, {"t_s", e.t_s ? json(*e.t_s) : json(nullptr)}, {"at", e.at},
                      {"kind", std::string(storage::to_string(e.kind))}, {"detail", std::move(detail)}});
  }
  json models = json::array();
  for (const auto& u : d->run.units) {
    auto ms = store.list_models(u.serial);
    if (!ms) return std::unexpected(from_store(ms.error()));
    for (const auto& m : *ms)
      if (m.run_id == run_id) {
        json one = {{"id", m.id}, {"serial", m.serial}, {"version", m.version},
                    {"unit", u.unit_index}, {"terms", m.terms}, {"method", m.method},
                    {"parent_id", m.parent_id ? json(*m.parent_id) : json(nullptr)}};
        if (!m.axis.empty()) one["axis"] = m.axis;  // a three-axis unit's model of that axis
        models.push_back(std::move(one));
      }
  }
  auto vs = store.list_verifications(run_id);
  if (!vs) return std::unexpected(from_store(vs.error()));
  json vers = json::array();
  for (const auto& v : *vs)
    vers.push_back({{"id", v.id}, {"unit", v.unit_index}, {"model_id", v.model_id},
                    {"pass", v.pass}, {"result", parse_or_string(v.result_json)}});
  json samples = json::array();
  for (const auto& u : d->run.units) {
    auto n = store.count_samples(run_id, u.unit_index);
    samples.push_back(n ? *n : 0);
  }
  // Each unit's verdict (issue 24, verdict.hpp): the one this run decided, or, on a plan's run
  // that did not decide it, the plan's when it has decided, else who will.
  auto decided = store.run_verdicts(run_id);
  if (!decided) return std::unexpected(from_store(decided.error()));
  const auto plan_id = verdict::plan_of_run(*d);
  json verdicts = json::array();
  for (const auto& u : d->run.units) {
    json v = nullptr;
    for (const auto& rec : *decided)
      if (rec.unit_index == u.unit_index) v = verdict::to_json(rec);  // the latest of this run
    if (v.is_null() && plan_id) {
      auto latest = store.latest_verdict(u.serial);
      if (!latest) return std::unexpected(from_store(latest.error()));
      if (*latest && (*latest)->plan_id == plan_id) v = verdict::to_json(**latest);
      else v = {{"serial", u.serial}, {"verdict", nullptr}, {"rule", "plan"}, {"plan", {{"id", *plan_id}}},
                {"pending", "plan " + std::to_string(*plan_id) + " decides it"}};
    }
    if (v.is_object()) v["unit"] = u.unit_index;
    verdicts.push_back(std::move(v));
  }
  auto identity = store.get_run_identity(run_id);
  if (!identity) return std::unexpected(from_store(identity.error()));
  return json{{"run", r}, {"samples", samples}, {"quality", quality}, {"events", events}, {"models", models},
              {"verifications", vers}, {"verdicts", verdicts}, {"config", parse_or_string(d->run.config_json)},
              {"profile_text", d->run.profile_text}, {"identity", identity_json(*identity)}};
}

ApiResult<json> run_samples(storage::Store& store, std::int64_t run_id, const json& req, std::int64_t offset,
                            std::int64_t limit) {
  auto ru = resolve_run_unit(store, run_id, req);
  if (!ru) return std::unexpected(ru.error());
  const int unit = ru->unit_index;
  auto total = store.count_samples(run_id, unit);
  if (!total) return std::unexpected(from_store(total.error()));
  auto rows = store.get_samples(run_id, unit, offset, limit);
  if (!rows) return std::unexpected(from_store(rows.error()));
  json arr = json::array();
  for (const auto& r : *rows) arr.push_back(sample_json(r, ru->axes));
  return json{{"run_id", run_id}, {"unit", unit}, {"offset", offset}, {"total", *total}, {"samples", arr}};
}

}  // namespace fogbench::daemon
