// What every section of fogbenchd's configuration shares in its checks (config.cpp,
// web_config.cpp, config_plant.cpp): the one refusal of an unknown field.
#pragma once

#include <expected>
#include <initializer_list>
#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

namespace fogbench::daemon::config_fields {

// `path.key`, or `key` at the top level.
inline std::string join(const std::string& path, const std::string& key) {
  return path.empty() ? key : path + "." + key;
}

// Unknown keys are refused so that a typo is an error, not a silently ignored setting:
// "socket.tcp.tokn: unknown field".
inline std::expected<void, std::string> only_keys(const nlohmann::json& obj, const std::string& path,
                                                  std::initializer_list<std::string_view> allowed) {
  for (const auto& [key, value] : obj.items()) {
    bool known = false;
    for (std::string_view a : allowed) known = known || a == key;
    if (!known) return std::unexpected(join(path, key) + ": unknown field");
  }
  return {};
}

}  // namespace fogbench::daemon::config_fields
