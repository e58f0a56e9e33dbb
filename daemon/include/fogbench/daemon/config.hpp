// fogbenchd's configuration file: the bench's drivers, storage, command socket, chamber limits,
// safe setpoint, profile directory and analysis defaults. Every refusal names the field
// ("chamber_limits.max_c: expected a number"). The shape is documented in docs/daemon.md.
#pragma once

#include <cstdint>
#include <expected>
#include <filesystem>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "fogbench/drivers/config.hpp"
#include "fogbench/profiles/profile.hpp"

namespace fogbench::daemon {

struct SocketConfig {
  std::filesystem::path unix_path = "/run/fogbench/fogbenchd.sock";
  std::optional<std::uint16_t> tcp_port;  // bound to 127.0.0.1 only when given
};

struct AnalysisConfig {
  std::string terms = "paper";    // term list of automatic fits (model/terms.hpp)
  std::string method = "paper";   // paper | joint
  double verify_threshold = 0.2;  // compensated/raw std ratio a verification must stay under
};

struct DaemonConfig {
  bool simulated = false;                  // --time-scale is refused unless true
  std::filesystem::path storage_path;      // the SQLite store
  bool storage_synchronous_full = true;    // fsync every commit (see storage's OpenOptions)
  SocketConfig socket;
  profiles::ChamberLimits limits;
  double safe_setpoint_c = 20.0;
  std::filesystem::path profile_dir;
  AnalysisConfig analysis;
  drivers::DriversConfig drivers;
  nlohmann::json source;                   // the file as read, stored with every run
};

// Parses the configuration; relative paths are resolved against base_dir (the file's folder).
std::expected<DaemonConfig, std::string> parse_daemon_config(const nlohmann::json& j,
                                                             const std::filesystem::path& base_dir);
// Reads and parses a file; errors start with the file name.
std::expected<DaemonConfig, std::string> load_daemon_config(const std::filesystem::path& file);

}  // namespace fogbench::daemon
