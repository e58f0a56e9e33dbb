// The rate-table kinds: one table of {kind, what it is, how to open it}, as chamber_registry.hpp
// is for chambers. A caller opens its table here by the configuration's `kind` and never names a
// concrete driver; adding a kind is one row and one driver file (docs/adding-a-device.md).
#pragma once

#include <memory>
#include <span>
#include <string>
#include <string_view>

#include "fogbench/drivers/error.hpp"
#include "fogbench/drivers/rate_table.hpp"

namespace fogbench::drivers {

struct RateTableKind {
  std::string_view name;         // the configuration's "kind"
  std::string_view description;  // for messages and docs
  std::uint16_t default_tcp_port;
  // Builds the driver; no I/O (the first call connects). Empty clocks: the real ones.
  std::unique_ptr<RateTable> (*open)(const RateTableConfig& config, RateTable::WallClock wall,
                                     RateTable::MonotonicClock clock);
};

std::span<const RateTableKind> rate_table_kinds() noexcept;
const RateTableKind* find_rate_table_kind(std::string_view name) noexcept;
std::string known_rate_table_kinds();  // "acutrol", for messages

// The table its configuration describes; `config` error naming the kind and the known ones
// when the kind is not in the table.
Result<std::unique_ptr<RateTable>> open_rate_table(const RateTableConfig& config,
                                                   RateTable::WallClock wall = {},
                                                   RateTable::MonotonicClock clock = {});

}  // namespace fogbench::drivers
