// The station's side of the plant store (issue 14): a completed run is queued in the bench's
// outbox once its end-of-run analysis is stored, and `status` shows the outbox. The sending is
// PlantLink's (plant_link.hpp), on its own thread.
#include <spdlog/spdlog.h>

#include <algorithm>

#include "fogbench/daemon/station.hpp"
#include "fogbench/plant/plant.hpp"
#include "fogbench/storage/outbox.hpp"
#include "fogbench/storage/store.hpp"

namespace fogbench::daemon {

using nlohmann::json;

void Station::queue_for_plant(std::int64_t run_id) {
  // A failure here (a full disk) leaves the run out of the outbox until the daemon restarts:
  // PlantLink then queues every completed run never queued.
  if (auto q = store_.enqueue_replication(run_id); !q)
    spdlog::error("plant: run {} not queued for the plant: {} (queued at the next start)", run_id,
                  q.error().message);
}

json Station::plant_status() const {
  auto o = store_.outbox_status();
  if (!o) {
    json e = {{"bench_id", config_.plant->bench_id}, {"error", o.error().message}};
    if (plant_link_state_) e.update(plant_link_state_());
    return e;
  }
  auto opt = [](const std::optional<std::string>& v) { return v ? json(*v) : json(nullptr); };
  json out = {{"bench_id", config_.plant->bench_id},
          {"outbox_depth", o->depth},
          {"sent", o->sent},
          {"oldest_queued_at", opt(o->oldest_queued_at)},
          {"attempts", o->attempts},
          {"last_error", o->last_error.empty() ? json(nullptr) : json(o->last_error)},
          {"last_sent_at", opt(o->last_sent_at)}};
  if (plant_link_state_) out.update(plant_link_state_());
  return out;
}

}  // namespace fogbench::daemon

namespace fogbench::daemon {

ApiResult<std::vector<std::optional<std::string>>> Station::unit_lots(const json& command,
                                                                      const std::vector<std::string>& serials) {
  std::vector<std::optional<std::string>> lots(serials.size());
  if (!command.is_object()) return lots;
  const bool one = command.contains("lot"), each = command.contains("lots");
  if (one && each) return api_error(ErrorCode::bad_request, "lot, lots: give one lot for every unit or lots by serial, not both");
  if (one) {
    if (!command["lot"].is_string()) return api_error(ErrorCode::bad_request, "lot: expected a string");
    const std::string lot = command["lot"].get<std::string>();
    if (auto why = plant::check_id(lot, "lot"); !why.empty()) return api_error(ErrorCode::bad_request, why);
    for (auto& l : lots) l = lot;
  }
  if (each) {
    if (!command["lots"].is_object()) return api_error(ErrorCode::bad_request, "lots: expected an object {serial: lot}");
    for (const auto& [serial, v] : command["lots"].items()) {
      auto it = std::find(serials.begin(), serials.end(), serial);
      if (it == serials.end()) return api_error(ErrorCode::bad_request, "lots." + serial + ": not one of the run's units");
      if (!v.is_string()) return api_error(ErrorCode::bad_request, "lots." + serial + ": expected a string");
      if (auto why = plant::check_id(v.get<std::string>(), "lots." + serial); !why.empty())
        return api_error(ErrorCode::bad_request, why);
      lots[static_cast<std::size_t>(it - serials.begin())] = v.get<std::string>();
    }
  }
  return lots;
}

}  // namespace fogbench::daemon
