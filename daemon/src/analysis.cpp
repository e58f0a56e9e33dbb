// The analysis of stored runs, split into what reads and computes (off the loop, on the analysis
// worker's read connection) and what stores (on the loop). See analysis.hpp.
#include "fogbench/daemon/analysis.hpp"

#include <algorithm>
#include <cmath>

#include <spdlog/spdlog.h>

#include "fogbench/model/json.hpp"
#include "fogbench/model/model.hpp"
#include "fogbench/model/terms.hpp"
#include "fogbench/model/workbench.hpp"
#include "fogbench/storage/models.hpp"
#include "fogbench/storage/run_data.hpp"

namespace fogbench::daemon::analysis {

using nlohmann::json;

namespace {

// A value not read is stored as NULL and exported as NaN with the sample flagged `missing`.
// model::fit skips flagged samples in the regression, but its lag scan and smoothers run over
// every sample; before model commit e6a8890 a NaN spread through them and failed the fit
// ("degenerate"). The gap is bridged (storage::bridge_missing; the flag stays, so the fit still
// skips the sample), which keeps the daemon's fits independent of how model/ treats NaN.
using storage::bridge_missing;

// A stored run's unit with its serial, gaps bridged for analysis.
struct UnitRun {
  std::string serial;
  model::RunData data;
};

ApiResult<std::string> serial_of(storage::Store& store, std::int64_t run_id, int unit_index) {
  auto detail = store.get_run(run_id);
  if (!detail) return std::unexpected(from_store(detail.error()));
  if (unit_index < 0 || unit_index >= static_cast<int>(detail->run.units.size()))
    return api_error(ErrorCode::not_found, "run " + std::to_string(run_id) + " has no unit " +
                                               std::to_string(unit_index));
  return detail->run.units[static_cast<std::size_t>(unit_index)].serial;
}

// The loading every analysis shares: the unit's serial and its samples, gaps bridged. The run
// keeps the store's name ("run N unit U (SERIAL)": fit and verify record it); the workbench's
// reports call it "run N SERIAL" (`workbench_name`).
ApiResult<UnitRun> load_unit_run(storage::Store& store, std::int64_t run_id, int unit_index,
                                 bool workbench_name = false, std::optional<model::Axis> axis = std::nullopt) {
  auto serial = serial_of(store, run_id, unit_index);
  if (!serial) return std::unexpected(serial.error());
  UnitRun u;
  u.serial = *serial;
  auto data = store.export_run(run_id, unit_index);
  if (!data) return std::unexpected(from_store(data.error()));
  u.data = std::move(*data);
  if (workbench_name) u.data.name = "run " + std::to_string(run_id) + " " + u.serial;
  if (axis) {
    auto picked = model::select_axis(std::move(u.data), *axis);
    if (!picked) return api_error(ErrorCode::bad_request, picked.error());
    u.data = std::move(*picked);
  }
  bridge_missing(u.data);
  return u;
}

// The storage name of an axis asked for; x when none is (a one-axis unit's model is x's).
std::string axis_name(std::optional<model::Axis> axis) {
  return std::string(model::to_string(axis.value_or(model::Axis::x)));
}

ApiResult<storage::ModelRecord> model_for(storage::Store& store, const std::string& serial,
                                          std::optional<std::int64_t> model_id, const char* none,
                                          std::optional<model::Axis> axis = std::nullopt) {
  if (model_id) {
    auto r = store.get_model(*model_id);
    if (!r) return std::unexpected(from_store(r.error()));
    return *r;
  }
  auto r = store.current_model(serial, axis_name(axis));
  if (!r) return std::unexpected(from_store(r.error()));
  if (!*r)
    return api_error(ErrorCode::unknown_serial,
                     "unit " + serial + (axis ? " axis " + axis_name(axis) : std::string()) + ": " + none);
  return **r;
}

// A stored unit's run with the model to work on: the one asked for, or the serial's current.
struct UnitWithModel {
  UnitRun unit;
  storage::ModelRecord record;
  model::Model model;
};

ApiResult<UnitWithModel> load_unit_with_model(storage::Store& store, std::int64_t run_id, int unit_index,
                                              std::optional<std::int64_t> model_id,
                                              const char* none = "no model yet (fit one first)",
                                              bool workbench_name = true,
                                              std::optional<model::Axis> axis = std::nullopt) {
  auto u = load_unit_run(store, run_id, unit_index, workbench_name, axis);
  if (!u) return std::unexpected(u.error());
  auto rec = model_for(store, u->serial, model_id, none, axis);
  if (!rec) return std::unexpected(rec.error());
  auto m = model::model_from_text(rec->model_json);
  if (!m) return api_error(ErrorCode::internal, "model " + std::to_string(rec->id) + ": " + m.error());
  return UnitWithModel{std::move(*u), std::move(*rec), std::move(*m)};
}

// A Commit that stores nothing: the result is ready.
Commit ready(json result) {
  auto r = std::make_shared<const json>(std::move(result));
  return [r](storage::Store&) -> ApiResult<json> { return *r; };
}

}  // namespace

ApiResult<Commit> fit(storage::Store& reader, const AnalysisConfig& config, std::int64_t run_id, int unit_index,
                      const std::string& terms_text, const std::string& method_text, const std::string& created_at,
                      std::optional<model::Axis> axis) {
  auto unit = load_unit_run(reader, run_id, unit_index, false, axis);
  if (!unit) return std::unexpected(unit.error());
  const std::string tt = terms_text.empty() ? config.terms : terms_text;
  auto terms = model::parse_terms(tt);
  if (!terms) return api_error(ErrorCode::bad_request, "terms: not a term list: " + tt);
  model::FitOptions opt;
  const std::string mt = method_text.empty() ? config.method : method_text;
  auto method = model::method_from_string(mt);
  if (!method) return api_error(ErrorCode::bad_request, "method: expected \"paper\" or \"joint\"");
  opt.method = *method;
  opt.max_iterations = config.max_iterations;
  opt.causal_lags = config.causal_lags;
  auto m = model::fit(unit->data, *terms, opt);
  if (!m) return std::unexpected(from_fit("fit failed", m.error()));
  m->created_at = created_at;
  // A joint fit whose iterations did not settle is still stored (the best estimate there is),
  // but never silently: the reply and the run's note say so, and the log.
  std::string warning;
  if (m->method == model::Method::joint && !m->fit.converged)
    warning = "the joint fit did not converge in " + std::to_string(m->fit.iterations) +
              (m->fit.iterations == 1 ? " iteration" : " iterations") + " (analysis.max_iterations " +
              std::to_string(config.max_iterations) + "): its coefficients may still move; check it before use";
  auto fitted = std::make_shared<const model::Model>(std::move(*m));
  return Commit([fitted, warning, serial = unit->serial, run_id, unit_index, axis](storage::Store& writer) -> ApiResult<json> {
    const model::Model& mo = *fitted;
    // The parent is the serial's current model (of the axis) when this one is stored, not when
    // the fit began.
    auto parent = writer.current_model(serial, axis_name(axis));
    if (!parent) return std::unexpected(from_store(parent.error()));
    storage::NewModel nm;
    nm.serial = serial;
    nm.run_id = run_id;
    if (*parent) nm.parent_id = (*parent)->id;
    json mj = model::to_json(mo);
    nm.model_json = mj.dump();
    nm.method = std::string(model::to_string(mo.method));
    nm.terms = mo.terms_string();
    auto ref = writer.put_model(nm);
    if (!ref) return std::unexpected(from_store(ref.error()));
    json result{{"model_id", ref->id}, {"version", ref->version}, {"serial", serial},
                {"run_id", run_id}, {"unit", unit_index},
                {"parent_id", nm.parent_id ? json(*nm.parent_id) : json(nullptr)},
                {"terms", nm.terms}, {"method", nm.method},
                // Samples the fit skipped for their quality flags (missing, frames lost, link gap, ...).
                {"n_flagged", mo.fit.n_flagged}, {"model", mj}};
    if (axis) result["axis"] = axis_name(axis);
    if (!warning.empty()) {
      result["warning"] = warning;
      spdlog::warn("model {} for {} (run {}): {}", ref->id, serial, run_id, warning);
    }
    return result;
  });
}

ApiResult<Commit> verify(storage::Store& reader, const AnalysisConfig& config, std::int64_t run_id, int unit_index,
                         std::optional<std::int64_t> model_id, std::optional<model::Axis> axis) {
  auto um = load_unit_with_model(reader, run_id, unit_index, model_id, "no model to verify", false, axis);
  if (!um) return std::unexpected(um.error());
  model::VerifyOptions vo;
  vo.threshold = config.verify_threshold;
  vo.noise.max_noise_factor = config.verify_max_noise_factor;
  vo.noise.max_fail_s = config.verify_max_fail_s;
  auto v = model::verify(um->model, um->unit.data, vo);
  if (!v) return std::unexpected(from_fit("verification failed", v.error()));
  json stored = model::to_json(*v);
  // The second test's limits in effect for this verdict, stored with it: a certificate states
  // these, not the configuration of the day it is printed (docs/cli.md, fogctl cert).
  stored["max_noise_factor"] = vo.noise.max_noise_factor;
  stored["max_fail_s"] = vo.noise.max_fail_s;
  if (axis) stored["axis"] = axis_name(axis);  // a three-axis unit's: which of its axes
  auto vj = std::make_shared<const json>(std::move(stored));
  const bool pass = v->pass;
  const std::int64_t mid = um->record.id;
  return Commit([vj, pass, mid, serial = um->unit.serial, run_id, unit_index](storage::Store& writer) -> ApiResult<json> {
    storage::NewVerification nv{run_id, unit_index, mid, vj->dump(), pass};
    auto id = writer.put_verification(nv);
    if (!id) return std::unexpected(from_store(id.error()));
    return json{{"verification_id", *id}, {"run_id", run_id}, {"unit", unit_index},
                {"serial", serial}, {"model_id", mid}, {"pass", pass}, {"result", *vj}};
  });
}

ApiResult<Commit> compare(storage::Store& reader, std::int64_t run_id, int unit_index,
                          std::optional<std::int64_t> model_id) {
  auto um = load_unit_with_model(reader, run_id, unit_index, model_id);
  if (!um) return std::unexpected(um.error());
  auto c = model::workbench::compare(um->model, um->unit.data);
  if (!c) return std::unexpected(from_fit("compare failed", c.error()));
  return ready(json{{"run_id", run_id}, {"unit", unit_index}, {"serial", um->unit.serial},
                    {"model_id", um->record.id}, {"result", model::workbench::to_json(*c)}});
}

ApiResult<Commit> diagnose(storage::Store& reader, std::int64_t run_id, int unit_index,
                           std::optional<std::int64_t> model_id, const std::vector<std::int64_t>& held_out_runs) {
  auto um = load_unit_with_model(reader, run_id, unit_index, model_id);
  if (!um) return std::unexpected(um.error());
  const UnitRun& u = um->unit;
  // Held-out runs: the same gyro (serial) in other stored runs.
  std::vector<model::RunData> held;
  for (std::int64_t other : held_out_runs) {
    auto d = reader.get_run(other);
    if (!d) return std::unexpected(from_store(d.error()));
    int idx = -1;
    for (const auto& ru : d->run.units)
      if (ru.serial == u.serial) idx = ru.unit_index;
    if (idx < 0)
      return api_error(ErrorCode::not_found, "held_out run " + std::to_string(other) + " has no unit " + u.serial);
    auto h = load_unit_run(reader, other, idx, true);
    if (!h) return std::unexpected(h.error());
    held.push_back(std::move(h->data));
  }
  auto dg = model::workbench::diagnose(um->model, u.data, held);
  if (!dg) return std::unexpected(from_fit("diagnose failed", dg.error()));
  return ready(json{{"run_id", run_id}, {"unit", unit_index}, {"serial", u.serial}, {"model_id", um->record.id},
                    {"held_out", held_out_runs}, {"result", model::workbench::to_json(*dg)}});
}

ApiResult<Commit> add_term(storage::Store& reader, std::int64_t run_id, int unit_index, const std::string& term,
                           std::optional<std::int64_t> model_id, const std::string& created_at) {
  auto um = load_unit_with_model(reader, run_id, unit_index, model_id);
  if (!um) return std::unexpected(um.error());
  auto added = model::workbench::add_term(um->model, um->unit.data, term);
  if (!added) return std::unexpected(from_fit("add_term failed", added.error()));
  added->model.created_at = created_at;
  auto nm = std::make_shared<storage::NewModel>();
  nm->serial = um->unit.serial;
  nm->run_id = run_id;
  nm->parent_id = um->record.id;
  auto mj = std::make_shared<const json>(model::to_json(added->model));
  nm->model_json = mj->dump();
  nm->method = std::string(model::to_string(added->model.method));
  nm->terms = added->model.terms_string();
  auto what = std::make_shared<const json>(added->added);
  return Commit([nm, mj, what, run_id, unit_index](storage::Store& writer) -> ApiResult<json> {
    auto ref = writer.put_model(*nm);
    if (!ref) return std::unexpected(from_store(ref.error()));
    return json{{"model_id", ref->id}, {"version", ref->version}, {"serial", nm->serial},
                {"run_id", run_id}, {"unit", unit_index}, {"parent_id", *nm->parent_id},
                {"added", *what}, {"terms", nm->terms}, {"method", nm->method}, {"model", *mj}};
  });
}

}  // namespace fogbench::daemon::analysis
