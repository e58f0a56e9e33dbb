// The table of chamber kinds: the one place a configuration's "kind" becomes a driver.
#include "fogbench/drivers/chamber_registry.hpp"

#include <nlohmann/json.hpp>

#include <array>

#include "fogbench/drivers/chamber_dialects.hpp"
#include "fogbench/drivers/espec_chamber.hpp"
#include "fogbench/drivers/simserv_chamber.hpp"
#include "json_fields.hpp"

namespace fogbench::drivers {

namespace {

using nlohmann::json;

Result<void> parse_link(const json& value, const std::string& path, std::uint16_t default_port,
                        bool serial_allowed, ChamberConfig& out) {
  const auto lp = detail::join_path(path, "link");
  if (!value.contains("link")) return detail::config_error(lp, "missing (expected an object)");
  auto line = parse_line_endpoint(value["link"], lp, default_port, serial_allowed);
  if (!line) return std::unexpected(line.error());
  out.line = *line;
  return {};
}

Result<void> parse_espec(const json& value, const std::string& path, const std::filesystem::path&,
                         ChamberConfig& out) {
  return parse_link(value, path, espec::default_tcp_port, true, out);
}

Result<void> parse_simserv(const json& value, const std::string& path, const std::filesystem::path&,
                           ChamberConfig& out) {
  if (auto ok = parse_link(value, path, simserv::default_tcp_port, false, out); !ok) return ok;
  auto index = detail::get_int_or(value, path, "chamber_index", 1, 99, 1);
  if (!index) return std::unexpected(index.error());
  out.simserv_chamber_index = static_cast<int>(*index);
  return {};
}

constexpr std::array<std::string_view, 2> modbus_fields{"modbus", "map"};
constexpr std::array<std::string_view, 1> espec_fields{"link"};
constexpr std::array<std::string_view, 2> simserv_fields{"link", "chamber_index"};

const std::array<ChamberKind, 3> kinds{{
    {"modbus", "a controller over Modbus TCP or RTU, addressed through a register map", modbus_fields,
     parse_modbus_chamber_fields,
     [](const ChamberConfig& c) -> std::unique_ptr<Chamber> { return std::make_unique<ModbusChamber>(c); }},
    {"espec", "Espec P300 / SCP-220 ASCII command set, over TCP or a serial port", espec_fields, parse_espec,
     [](const ChamberConfig& c) -> std::unique_ptr<Chamber> { return std::make_unique<EspecChamber>(c); }},
    {"simserv", "Weiss / Voetsch SIMSERV over TCP", simserv_fields, parse_simserv,
     [](const ChamberConfig& c) -> std::unique_ptr<Chamber> { return std::make_unique<SimservChamber>(c); }},
}};

}  // namespace

std::span<const ChamberKind> chamber_kinds() noexcept { return kinds; }

const ChamberKind* find_chamber_kind(std::string_view name) noexcept {
  for (const auto& k : kinds) {
    if (k.name == name) return &k;
  }
  return nullptr;
}

std::string known_chamber_kinds() {
  std::string out;
  for (const auto& k : kinds) {
    if (!out.empty()) out += ", ";
    out += k.name;
  }
  return out;
}

Result<std::unique_ptr<Chamber>> open_chamber(const ChamberConfig& config) {
  const ChamberKind* kind = find_chamber_kind(config.kind);
  if (kind == nullptr) {
    return fail(ErrorCode::config, "chamber.kind: unknown chamber kind '" + config.kind + "' (known: " +
                                       known_chamber_kinds() + ")");
  }
  return kind->open(config);
}

}  // namespace fogbench::drivers
