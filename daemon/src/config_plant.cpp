// The `plant` section of fogbenchd's configuration (issue 14, docs/daemon.md and docs/plant.md).
#include <cmath>
#include <cstdint>

#include "fogbench/daemon/config.hpp"
#include "config_fields.hpp"
#include "fogbench/plant/plant.hpp"

namespace fogbench::daemon {

std::expected<PlantConfig, std::string> parse_plant_config(const nlohmann::json& j) {
  using Err = std::unexpected<std::string>;
  if (!j.is_object()) return Err("plant: expected an object {\"conninfo\", \"bench_id\"}");
  if (auto ok = config_fields::only_keys(j, "plant", config_fields::kPlantKeys); !ok)
    return Err(ok.error());
  PlantConfig p;
  if (!j.contains("conninfo") || !j["conninfo"].is_string() || j["conninfo"].get<std::string>().empty())
    return Err("plant.conninfo: expected a libpq connection string, e.g. \"service=plant\"");
  p.conninfo = j["conninfo"].get<std::string>();
  if (!j.contains("bench_id") || !j["bench_id"].is_string())
    return Err("plant.bench_id: expected this bench's name in the plant (1..64 characters)");
  p.bench_id = j["bench_id"].get<std::string>();
  if (auto why = plant::check_id(p.bench_id, "plant.bench_id"); !why.empty()) return Err(why);
  for (auto [key, field, lo, hi] : {std::tuple{"poll_s", &p.poll_s, 0.01, 3600.0},
                                    std::tuple{"retry_max_s", &p.retry_max_s, 0.01, 86400.0},
                                    std::tuple{"stall_s", &p.stall_s, 0.5, 86400.0}}) {
    if (!j.contains(key)) continue;
    const auto& v = j[key];
    if (!v.is_number() || !std::isfinite(v.get<double>()) || v.get<double>() < lo || v.get<double>() > hi)
      return Err(std::string("plant.") + key + ": expected a number " + std::to_string(lo) + " to " +
                 std::to_string(hi) + " (s)");
    *field = v.get<double>();
  }
  if (j.contains("connect_timeout_s")) {
    const auto& v = j["connect_timeout_s"];
    if (!v.is_number_integer() || v.get<std::int64_t>() < 1 || v.get<std::int64_t>() > 3600)
      return Err("plant.connect_timeout_s: expected a whole number of seconds, 1 to 3600");
    p.connect_timeout_s = v.get<int>();
  }
  return p;
}

}  // namespace fogbench::daemon
