// Online compensation of each unit's rate while a run acquires (live_compensation.hpp).
#include "fogbench/daemon/live_compensation.hpp"

#include <cmath>

#include <spdlog/spdlog.h>

#include "fogbench/model/json.hpp"
#include "fogbench/model/run.hpp"
#include "fogbench/storage/models.hpp"
#include "fogbench/storage/store.hpp"

namespace fogbench::daemon {

namespace fw = model::firmware;

LiveCompensation LiveCompensation::load(storage::Store& store, const std::vector<std::string>& serials,
                                        const std::vector<std::optional<std::int64_t>>& model_ids) {
  LiveCompensation live;
  for (std::size_t i = 0; i < serials.size(); ++i) {
    Unit u;
    u.serial = serials[i];
    std::optional<storage::ModelRecord> rec;
    if (i < model_ids.size() && model_ids[i]) {
      auto m = store.get_model(*model_ids[i]);
      if (m) rec = *m;
      else u.none = "model " + std::to_string(*model_ids[i]) + " the run started with: " + m.error().message;
    } else if (!model_ids.empty()) {
      u.none = "none when the run started";  // a model fitted since is for the next run
    } else {
      auto m = store.current_model(serials[i]);
      if (!m) u.none = "reading the current model: " + m.error().message;
      else if (!*m) u.none = "no model";
      else rec = **m;
    }
    if (rec) {
      u.model_id = rec->id;
      u.model_version = rec->version;
      auto parsed = model::model_from_text(rec->model_json);
      if (!parsed) {
        u.none = "model " + std::to_string(rec->id) + ": " + parsed.error();
      } else if (auto p = fw::compile(*parsed); !p) {
        u.none = "model " + std::to_string(rec->id) + " has no firmware form: " + p.error();
      } else {
        u.program = std::make_unique<fw::Program>(std::move(*p));
        u.used = fw::inputs_used(*u.program);
        u.warm_up = fw::warm_up_samples(*u.program);
      }
    }
    if (!u.none.empty()) spdlog::info("unit {}: no live compensation ({})", u.serial, u.none);
    live.units_.push_back(std::move(u));
  }
  return live;
}

std::vector<std::optional<std::int64_t>> LiveCompensation::recorded_models(const storage::RunDetail& run) {
  std::vector<std::optional<std::int64_t>> ids;
  for (const auto& e : run.events) {
    if (e.kind != storage::EventKind::note) continue;
    auto j = nlohmann::json::parse(e.detail_json, nullptr, false);
    if (!j.is_object() || !j.contains("live_compensation") || !j["live_compensation"].is_array()) continue;
    for (const auto& u : j["live_compensation"]) {
      const auto& id = u.is_object() ? u.value("model_id", nlohmann::json()) : nlohmann::json();
      ids.push_back(id.is_number_integer() ? std::optional(id.get<std::int64_t>()) : std::nullopt);
    }
    break;
  }
  return ids;
}

nlohmann::json LiveCompensation::describe() const {
  nlohmann::json units = nlohmann::json::array();
  for (std::size_t i = 0; i < units_.size(); ++i) {
    const Unit& u = units_[i];
    nlohmann::json j = {{"unit", i}, {"serial", u.serial}};
    if (u.model_id) {
      j["model_id"] = *u.model_id;
      j["model_version"] = u.model_version;
    }
    if (u.program) j["warm_up_s"] = u.warm_up * u.program->dt_s;
    else j["none"] = u.none;
    units.push_back(std::move(j));
  }
  return {{"live_compensation", units}};
}

double LiveCompensation::step(std::size_t i, const storage::SampleRow& row) {
  if (i >= units_.size()) return storage::kNoValue;
  Unit& u = units_[i];
  if (!u.program) return storage::kNoValue;
  const bool good = (!u.used.t1 || std::isfinite(row.t1_c)) && (!u.used.t2 || std::isfinite(row.t2_c)) &&
                    (!u.used.ta || std::isfinite(row.chamber_c)) && (!u.used.ton || std::isfinite(row.since_power_on_s)) &&
                    (row.flags & model::flag::out_of_range) == 0;
  if (!good) {
    u.comp.reset();  // re-warm from the next good second
    u.steps = 0;
    return storage::kNoValue;
  }
  if (!u.comp) u.comp.emplace(*u.program);
  fw::Input in;
  in.t1_c = u.used.t1 ? row.t1_c : 0.0;
  in.t2_c = u.used.t2 ? row.t2_c : 0.0;
  in.ta_c = u.used.ta ? row.chamber_c : 0.0;
  in.ton_s = u.used.ton ? row.since_power_on_s : 0.0;
  const double mu_dph = u.comp->step(in);
  const bool warm = u.steps++ >= u.warm_up;
  if (!warm || !std::isfinite(row.gyro_dph)) return storage::kNoValue;
  return row.gyro_dph - mu_dph;
}

}  // namespace fogbench::daemon
