// The chamber kinds: one table of {kind, what it is, its configuration fields, how to open it},
// as chrony's refclock table maps a configuration name to a driver. The daemon opens its chamber
// here by the configuration's `kind` and never names a concrete driver; adding a kind is one row
// and one driver file (docs/adding-a-device.md).
#pragma once

#include <nlohmann/json_fwd.hpp>

#include <filesystem>
#include <memory>
#include <span>
#include <string>
#include <string_view>

#include "fogbench/drivers/chamber.hpp"
#include "fogbench/drivers/config.hpp"
#include "fogbench/drivers/error.hpp"

namespace fogbench::drivers {

struct ChamberKind {
  std::string_view name;         // the configuration's "kind"
  std::string_view description;  // for messages and docs
  // The fields this kind reads besides "kind", "pv_limits_c" and "setpoint_limits_c".
  std::span<const std::string_view> fields;
  // Reads those fields from the chamber object at `path` into `out`.
  Result<void> (*parse)(const nlohmann::json& chamber, const std::string& path,
                        const std::filesystem::path& map_dir, ChamberConfig& out);
  // Builds the driver; no I/O (the first call connects).
  std::unique_ptr<Chamber> (*open)(const ChamberConfig& config);
};

std::span<const ChamberKind> chamber_kinds() noexcept;
const ChamberKind* find_chamber_kind(std::string_view name) noexcept;
// "modbus, espec, simserv", for messages.
std::string known_chamber_kinds();

// The chamber its configuration describes; `config` error naming the kind and the known ones
// when the kind is not in the table.
Result<std::unique_ptr<Chamber>> open_chamber(const ChamberConfig& config);

}  // namespace fogbench::drivers
