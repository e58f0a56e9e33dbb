// Which bench slot (fixture position: a CAN node id and two thermistor channels, the
// configuration's units[]) each unit of a run sits in, and its serial, from a run.start (or
// plan.start, queue.add) request: serials are given per run, the configuration's only defaults.
// Pure: no I/O, tested without a daemon (docs/protocol.md, "Bench slots").
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "fogbench/daemon/api.hpp"
#include "fogbench/drivers/config.hpp"

namespace fogbench::daemon {

struct SlotUnit {
  std::size_t config_index = 0;  // into the configuration's drivers.units
  std::string serial;
};

// The run's units from the request's `units` (serials, each the configured default serial of a
// slot, as before slots) and `slots` ({slot: serial}); either or both. Their order (unit_index):
// `units` as given, then `slots` in the configuration's slot order. A slot not named takes no
// part in the run, whatever its default serial. Refused, naming the field, nothing started:
// `slots` not an object of strings; an unknown slot; a slot named twice (by `units` and
// `slots`); an empty serial, one with control characters, invalid UTF-8 or over
// storage::kMaxNameBytes bytes; one serial in two slots; a `units` serial that is no slot's
// default (unknown_serial, saying to give its slot). Neither given: `units: missing` when
// `required`, else an empty list.
ApiResult<std::vector<SlotUnit>> slot_units(const nlohmann::json& req,
                                            const std::vector<drivers::UnitConfig>& configured,
                                            bool required);

// The index (into `configured`) of the slot named `slot` when one is given, else of the slot
// whose configured default serial is `serial`; nullopt when there is none.
std::optional<std::size_t> find_slot(const std::vector<drivers::UnitConfig>& configured, std::string_view serial,
                                     std::optional<std::string_view> slot = std::nullopt);

// The serials of `units`, in order.
std::vector<std::string> serials_of(const std::vector<SlotUnit>& units);

}  // namespace fogbench::daemon
