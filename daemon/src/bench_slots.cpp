// A run's units from its request: slots named with their serials, or configured default serials
// (bench_slots.hpp).
#include "fogbench/daemon/bench_slots.hpp"

#include <algorithm>

#include "fogbench/storage/identity.hpp"

namespace fogbench::daemon {

namespace {

std::string slot_list(const std::vector<drivers::UnitConfig>& configured) {
  std::string s;
  for (const auto& u : configured) s += (s.empty() ? "" : ", ") + u.slot;
  return s;
}

}  // namespace

ApiResult<std::vector<SlotUnit>> slot_units(const nlohmann::json& req,
                                            const std::vector<drivers::UnitConfig>& configured,
                                            bool required) {
  const bool has_units = req.contains("units"), has_slots = req.contains("slots");
  if (!has_units && !has_slots) {
    if (required) return api_error(ErrorCode::bad_request, "units: missing (give units or slots)");
    return std::vector<SlotUnit>{};
  }
  std::vector<SlotUnit> out;
  std::vector<std::string> field_of;  // the request field that placed each of `out`
  auto place = [&](std::size_t ci, std::string serial, std::string field) -> ApiResult<void> {
    for (std::size_t k = 0; k < out.size(); ++k) {
      if (out[k].config_index == ci)
        return api_error(ErrorCode::bad_request, field + ": slot " + configured[ci].slot + " is already given by " + field_of[k]);
      if (out[k].serial == serial)
        return api_error(ErrorCode::bad_request, field + ": " + serial + " is already in " + field_of[k]);
    }
    out.push_back({ci, std::move(serial)});
    field_of.push_back(std::move(field));
    return {};
  };

  if (has_units) {
    auto serials = serials_field(req, false);  // api.cpp: an array of storable names
    if (!serials) return std::unexpected(serials.error());
    for (std::size_t i = 0; i < serials->size(); ++i) {
      const std::string& s = (*serials)[i];
      const std::string field = "units[" + std::to_string(i) + "]";
      if (s.empty()) return api_error(ErrorCode::bad_request, field + ": empty serial");
      const auto ci = find_slot(configured, s);
      if (!ci)
        return api_error(ErrorCode::unknown_serial, "unit " + s + ": not the default serial of any slot on this bench (" +
                                                        "give its slot: slots {\"A\": \"" + s + "\"}, fogctl --slot A=" + s + ")");
      if (auto ok = place(*ci, s, field); !ok) {
        // The same serial twice in `units` keeps its old message.
        if (std::count(serials->begin(), serials->end(), s) > 1)
          return api_error(ErrorCode::bad_request, "units: " + s + " given twice");
        return std::unexpected(ok.error());
      }
    }
  }
  if (has_slots) {
    const nlohmann::json& slots = req["slots"];
    if (!slots.is_object())
      return api_error(ErrorCode::bad_request, "slots: expected an object {slot: serial}, e.g. {\"A\": \"FOG-0042\"}");
    // In the configuration's order, so that the unit indices do not depend on the JSON's.
    for (const auto& [key, value] : slots.items()) {
      if (!find_slot(configured, {}, key))
        return api_error(ErrorCode::bad_request, "slots." + key + ": no such slot on this bench (slots: " + slot_list(configured) + ")");
      const std::string field = "slots." + key;
      if (!value.is_string()) return api_error(ErrorCode::bad_request, field + ": expected a serial (a string)");
      const std::string serial = value.get<std::string>();
      if (serial.empty()) return api_error(ErrorCode::bad_request, field + ": empty serial");
      if (auto why = storage::check_stored_text(field, serial, storage::kMaxNameBytes); !why.empty())
        return api_error(ErrorCode::bad_request, why);
    }
    for (std::size_t ci = 0; ci < configured.size(); ++ci) {
      auto it = slots.find(configured[ci].slot);
      if (it == slots.end()) continue;
      if (auto ok = place(ci, it->get<std::string>(), "slots." + configured[ci].slot); !ok) return std::unexpected(ok.error());
    }
  }
  if (out.empty()) return api_error(ErrorCode::bad_request, has_slots ? "slots: expected at least one slot" : "units: expected at least one serial");
  return out;
}

std::optional<std::size_t> find_slot(const std::vector<drivers::UnitConfig>& configured, std::string_view serial,
                                     std::optional<std::string_view> slot) {
  auto it = std::find_if(configured.begin(), configured.end(), [&](const auto& u) {
    return slot ? u.slot == *slot : !u.serial.empty() && u.serial == serial;
  });
  if (it == configured.end()) return std::nullopt;
  return static_cast<std::size_t>(it - configured.begin());
}

std::vector<std::string> serials_of(const std::vector<SlotUnit>& units) {
  std::vector<std::string> s;
  s.reserve(units.size());
  for (const auto& u : units) s.push_back(u.serial);
  return s;
}

}  // namespace fogbench::daemon
