// A run's identity as the daemon records it when the run is created (issue 13, docs/daemon.md
// "Run identity"): the station, the operator, fogbench's version and commit, the SHA-256 of the
// configuration and of the profile, each unit's power-on. Pure apart from peer_user_name.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "fogbench/daemon/api.hpp"
#include "fogbench/storage/identity.hpp"

namespace fogbench::daemon {

// Who started a run: the request's `operator`, else the unix peer's user.
struct OperatorId {
  std::string name;
  std::string source = "none";  // client | peer | none (storage/identity.hpp)
};

// From run.start's request and the session's peer: `operator` when given (checked: at most
// storage::kMaxOperatorBytes bytes, no control characters; else a bad_request naming
// `operator`), else the peer's user, else nobody.
ApiResult<OperatorId> operator_of(const nlohmann::json& request, const std::string& peer_user);

// The user of a connected unix socket (SO_PEERCRED and the password database): its name, or
// "uid N" when the uid has no name; "" when the credentials cannot be read.
std::string peer_user_name(int fd);

// A unit's power-on as the run is created: `since_power_on_s` (daemon seconds, empty when
// the daemon did not see it) and the wall time it happened (unix s).
struct UnitPowerOn {
  std::optional<double> since_power_on_s;
  std::optional<double> powered_on_wall_s;
};

// The identity: the configuration's hash is over config_json (the canonical JSON that is
// stored with the run: nlohmann's dump(), keys sorted, no whitespace), the profile's over its
// text's bytes as stored.
storage::RunIdentity make_run_identity(const std::string& station_id, const OperatorId& op,
                                       const std::string& config_json, const std::string& profile_text,
                                       const std::vector<std::string>& serials,
                                       const std::vector<UnitPowerOn>& power);

// ISO 8601 UTC of a unix time, to the second.
std::string iso8601_utc(double unix_s);

// The identity as JSON (run.get's `identity`, the certificate's runs), null when absent.
nlohmann::json identity_json(const std::optional<storage::RunIdentity>& id);

}  // namespace fogbench::daemon
