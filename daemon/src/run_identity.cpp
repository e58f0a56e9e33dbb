// A run's identity (run_identity.hpp): the operator from the request or the socket's peer, the
// hashes of what the run was configured with, each unit's power-on.
#include "fogbench/daemon/run_identity.hpp"

#include <pwd.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cmath>
#include <ctime>

#include "fogbench/model/sha256.hpp"
#include "fogbench/protocol/build_info.hpp"

namespace fogbench::daemon {

using nlohmann::json;

ApiResult<OperatorId> operator_of(const json& request, const std::string& peer_user) {
  if (request.contains("operator") && !request["operator"].is_null()) {
    const json& v = request["operator"];
    if (!v.is_string()) return api_error(ErrorCode::bad_request, "operator: expected a string");
    const std::string name = v.get<std::string>();
    if (name.empty()) return api_error(ErrorCode::bad_request, "operator: empty (leave it out to record the socket's user)");
    if (auto why = storage::check_operator_name(name); !why.empty()) return api_error(ErrorCode::bad_request, why);
    return OperatorId{name, "client"};
  }
  if (!peer_user.empty() && storage::check_operator_name(peer_user).empty()) return OperatorId{peer_user, "peer"};
  return OperatorId{};
}

std::string peer_user_name(int fd) {
  ucred cred{};
  socklen_t len = sizeof cred;
  if (::getsockopt(fd, SOL_SOCKET, SO_PEERCRED, &cred, &len) != 0 || len != sizeof cred) return {};
  passwd pw{};
  passwd* found = nullptr;
  char buf[4096];
  if (::getpwuid_r(cred.uid, &pw, buf, sizeof buf, &found) == 0 && found && found->pw_name)
    return found->pw_name;
  return "uid " + std::to_string(cred.uid);
}

std::string iso8601_utc(double unix_s) {
  const auto t = static_cast<std::time_t>(std::floor(unix_s));
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

storage::RunIdentity make_run_identity(const std::string& station_id, const OperatorId& op,
                                       const std::string& config_json, const std::string& profile_text,
                                       const std::vector<std::string>& serials,
                                       const std::vector<UnitPowerOn>& power) {
  storage::RunIdentity id;
  id.station_id = station_id;
  id.operator_name = op.name;
  id.operator_source = op.source;
  const auto& build = protocol::build_info();
  id.software_version = std::string(build.version);
  id.git_hash = std::string(build.git_hash);
  id.config_sha256 = model::sha256_hex(config_json);
  id.profile_sha256 = model::sha256_hex(profile_text);
  for (std::size_t i = 0; i < serials.size(); ++i) {
    storage::UnitIdentity u;
    u.unit_index = static_cast<int>(i);
    u.serial = serials[i];
    if (i < power.size()) {
      u.since_power_on_s = power[i].since_power_on_s;
      if (power[i].powered_on_wall_s) u.powered_on_at = iso8601_utc(*power[i].powered_on_wall_s);
    }
    id.units.push_back(std::move(u));
  }
  return id;
}

json identity_json(const std::optional<storage::RunIdentity>& id) {
  if (!id) return nullptr;
  json units = json::array();
  for (const auto& u : id->units)
    units.push_back({{"unit", u.unit_index}, {"serial", u.serial},
                     {"powered_on_at", u.powered_on_at ? json(*u.powered_on_at) : json(nullptr)},
                     {"since_power_on_s", u.since_power_on_s ? json(*u.since_power_on_s) : json(nullptr)}});
  return {{"station_id", id->station_id}, {"operator", id->operator_name}, {"operator_source", id->operator_source},
          {"software_version", id->software_version}, {"git_hash", id->git_hash},
          {"config_sha256", id->config_sha256}, {"profile_sha256", id->profile_sha256}, {"units", units}};
}

}  // namespace fogbench::daemon
