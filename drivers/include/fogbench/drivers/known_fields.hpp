// The one check that a JSON object holds only known fields, shared by every file fogbench reads
// (fogbenchd's configuration, the drivers' sections and register maps, the mock bench's --config
// file and its fault commands), so that a typo is refused in the same words everywhere:
//   "socket.tcp.tokn: unknown field (known: port, address, token, token_file, allow_remote)".
// In drivers_protocol because that is the lowest library all of them link (sim/mock links only it).
#pragma once

#include <initializer_list>
#include <optional>
#include <span>
#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

namespace fogbench::drivers {

// `path.key`, or `key` when path is empty (the top level).
std::string field_path(std::string_view path, std::string_view key);

// The refusal of the first field of `object` (in the object's order) that is not in `known`:
// "<path>.<key>: unknown field (known: <known, in the order given>)"; nothing when every field is
// known or `object` is not an object (the caller checks the type and says so in its own words).
// A caller adds where the object is (a file's name, a line) around it, never inside.
std::optional<std::string> unknown_field(const nlohmann::json& object, std::string_view path,
                                         std::span<const std::string_view> known);
std::optional<std::string> unknown_field(const nlohmann::json& object, std::string_view path,
                                         std::initializer_list<std::string_view> known);

}  // namespace fogbench::drivers
