// The station's status view: the daemon, the last second's readings, the active run with its
// quality counters, and how the last run ended (the `status` reply, docs/protocol.md).
#include "fogbench/daemon/station.hpp"

namespace fogbench::daemon {

using nlohmann::json;
using storage::RunState;

namespace {
// A JSON number, or null for a value not read (JSON has no NaN).
json num(std::optional<double> v) { return protocol::number_or_null(v); }
}  // namespace

json Station::unrecorded_end(std::int64_t run_id) const { return journal_.unrecorded_end(run_id); }

json Station::live_quality(std::int64_t run_id) const {
  if (!run_ || run_->id != run_id) return nullptr;
  return quality_json(*run_);
}

json Station::quality_json(const ActiveRun& run) {
  json q = json::array();
  for (std::size_t i = 0; i < run.serials.size(); ++i) {
    const ActiveRun::Quality z = i < run.quality.size() ? run.quality[i] : ActiveRun::Quality{};
    q.push_back({{"unit", i}, {"serial", run.serials[i]}, {"frames_lost", z.frames_lost},
                 {"frames_corrupt", z.frames_corrupt}, {"samples_flagged", z.samples_flagged}});
  }
  return q;
}

json Station::status() const {
  json s;
  s["version"] = FOGBENCH_DAEMON_VERSION;
  s["simulated"] = config_.simulated;
  s["time_scale"] = time_scale_;
  s["clock_s"] = clock_s_;
  s["setpoint_c"] = setpoint_c_;
  s["safe_setpoint_c"] = config_.safe_setpoint_c;
  s["limits"] = {{"min_c", config_.limits.min_c}, {"max_c", config_.limits.max_c},
                 {"max_rate_c_per_min", config_.limits.max_rate_c_per_min}};
  json chamber = {{"chamber_c", nullptr}, {"setpoint_c", nullptr}, {"alarm", false}, {"link", "unknown"}};
  json units = json::array();
  for (std::size_t i = 0; i < config_.drivers.units.size(); ++i) {
    // The slot's serial: the active run's unit in it, else the configured default (null: none).
    // A slot in use shows the name the run stored for it; a reload that renamed it since says
    // the new name in `next_slot` (the name of the next run's unit there).
    const auto& cu = config_.drivers.units[i];
    json serial = cu.serial.empty() ? json(nullptr) : json(cu.serial);
    std::string slot = cu.slot;
    if (run_) {
      for (std::size_t k = 0; k < run_->config_index.size() && k < run_->serials.size(); ++k)
        if (run_->config_index[k] == i) {
          serial = run_->serials[k];
          if (k < run_->slots.size()) slot = run_->slots[k];
        }
    }
    json u = {{"slot", slot}, {"serial", serial}, {"gyro_dph", nullptr},
              {"frames", 0}, {"t1_c", nullptr}, {"t2_c", nullptr}};
    if (slot != cu.slot) u["next_slot"] = cu.slot;
    if (last_input_ && i < last_input_->units.size()) {
      const auto& r = last_input_->units[i];
      u["gyro_dph"] = num(r.gyro_dph);
      u["frames"] = r.frames;
      u["t1_c"] = num(r.t1_c);
      u["t2_c"] = num(r.t2_c);
    }
    units.push_back(u);
  }
  if (last_input_) {
    chamber = {{"chamber_c", num(last_input_->chamber_c)},
               {"setpoint_c", num(last_input_->chamber_setpoint_c)},
               {"alarm", last_input_->chamber_alarm},
               {"link", last_input_->chamber_link_down ? "down" : "up"}};
  }
  s["chamber"] = chamber;
  s["units"] = units;
  if (run_) {
    const auto& r = *run_;
    const json run_slots = r.slots;  // as the run started (a reload may have renamed a slot since)
    s["run"] = {{"id", r.id}, {"state", std::string(storage::to_string(r.state))},
                {"profile", r.profile_name}, {"purpose", std::string(storage::to_string(r.purpose))},
                {"units", r.serials}, {"slots", run_slots}, {"elapsed_s", r.elapsed_s},
                {"remaining_s", r.executor ? json(r.last.remaining_s) : json(nullptr)},
                {"phase", r.phase ? json(std::string(profiles::to_string(*r.phase))) : json(nullptr)},
                {"step", r.step},
                {"steps", r.executor ? json(r.executor->profile().steps.size()) : json(nullptr)}, {"profile_held_s", r.held_s}, {"quality", quality_json(r)},
                {"link_gap_s", r.link_down_since_s ? json(r.elapsed_s - *r.link_down_since_s) : json(nullptr)},
                {"samples_pending", samples_->pending()}};
    if (r.state == RunState::pending) s["run"]["remaining_s"] = r.executor->profile().nominal_duration_s();
  } else {
    s["run"] = nullptr;
  }
  if (config_.plant) s["plant"] = plant_status();
  s["last_run"] = last_run_;
  // A run.resume whose stored seconds are being replayed on the worker (Station::resume_run_async);
  // absent otherwise.
  if (resuming_) s["resuming_run_id"] = *resuming_;
  s["recovery"] = recovery_error_ ? json{{"pending", true}, {"error", *recovery_error_}} : json(nullptr);
  if (last_run_.is_object()) {
    const auto id = last_run_["run_id"].get<std::int64_t>();
    s["last_run"]["recorded"] = !journal_.holds(id);
  }
  return s;
}

}  // namespace fogbench::daemon
