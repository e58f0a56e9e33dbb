// What every section of fogbenchd's configuration shares in its checks (config.cpp,
// web_config.cpp, config_plant.cpp): the one refusal of an unknown field.
#pragma once

#include <expected>
#include <span>
#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

#include "fogbench/drivers/known_fields.hpp"

namespace fogbench::daemon::config_fields {

// `path.key`, or `key` at the top level.
inline std::string join(const std::string& path, const std::string& key) { return drivers::field_path(path, key); }

// The keys each section of the file may hold: the parser refuses any other, and the reload's
// table (config_reload.cpp) is tested to classify every one of them. The drivers' sections are
// the drivers library's own (drivers/config.hpp).
inline constexpr std::string_view kTopKeys[] = {"simulated", "storage", "socket", "chamber_limits",
                                                "safe_setpoint_c", "profile_dir", "map_dir", "analysis",
                                                "link_loss", "tracking", "drivers", "sim_clock", "web",
                                                "station", "plant", "signing", "rate_table"};
inline constexpr std::string_view kStationKeys[] = {"id"};
inline constexpr std::string_view kStorageKeys[] = {"path", "synchronous", "size_limit_bytes"};
inline constexpr std::string_view kSigningKeys[] = {"key_path"};
inline constexpr std::string_view kSocketKeys[] = {"path", "group", "tcp_port", "tcp", "max_clients",
                                                   "unix_max_clients", "max_clients_per_address",
                                                   "max_analyses_per_address", "first_request_timeout_s",
                                                   "refusal_log_interval_s", "idle_timeout_s"};
inline constexpr std::string_view kSocketTcpKeys[] = {"port", "address", "token", "token_file", "allow_remote"};
inline constexpr std::string_view kChamberLimitsKeys[] = {"min_c", "max_c", "max_rate_c_per_min"};
inline constexpr std::string_view kAnalysisKeys[] = {"terms", "method", "verify_threshold", "verify_max_noise_factor",
                                                     "verify_max_fail_s", "max_iterations", "causal_lags"};
inline constexpr std::string_view kLinkLossKeys[] = {"policy", "tolerance_s"};
inline constexpr std::string_view kTrackingKeys[] = {"max_error_c", "for_s", "frozen_s"};
inline constexpr std::string_view kWebKeys[] = {"listen", "allow_remote", "enabled", "token_file", "hosts"};
inline constexpr std::string_view kPlantKeys[] = {"conninfo", "bench_id", "poll_s", "retry_max_s", "stall_s", "connect_timeout_s"};

struct Section {
  std::string_view path;  // "" for the top level
  std::span<const std::string_view> keys;
};
inline constexpr Section kSections[] = {
    {"", kTopKeys},           {"station", kStationKeys},     {"storage", kStorageKeys},
    {"signing", kSigningKeys}, {"socket", kSocketKeys},       {"socket.tcp", kSocketTcpKeys},
    {"chamber_limits", kChamberLimitsKeys}, {"analysis", kAnalysisKeys}, {"link_loss", kLinkLossKeys},
    {"tracking", kTrackingKeys}, {"web", kWebKeys},           {"plant", kPlantKeys}};

// Unknown keys are refused so that a typo is an error, not a silently ignored setting, by the
// check every file of fogbench shares (drivers/known_fields.hpp):
// "socket.tcp.tokn: unknown field (known: port, address, token, token_file, allow_remote)".
inline std::expected<void, std::string> only_keys(const nlohmann::json& obj, const std::string& path,
                                                  std::span<const std::string_view> allowed) {
  if (auto refusal = drivers::unknown_field(obj, path, allowed)) return std::unexpected(std::move(*refusal));
  return {};
}

}  // namespace fogbench::daemon::config_fields
