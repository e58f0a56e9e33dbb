// Parsing of fogbenchd's configuration file, field by field, with errors that name the field.
#include "fogbench/daemon/config.hpp"
#include "fogbench/daemon/config_reload.hpp"

#include <tuple>
#include <grp.h>

#include <boost/asio/ip/address.hpp>
#include <algorithm>
#include <cmath>
#include <fstream>
#include <set>
#include <sstream>

#include "fogbench/model/model.hpp"
#include "fogbench/model/terms.hpp"
#include "fogbench/storage/identity.hpp"
#include "config_fields.hpp"

namespace fogbench::daemon {
namespace {

using nlohmann::json;
using Err = std::unexpected<std::string>;

using config_fields::join;
using config_fields::only_keys;

std::expected<double, std::string> number(const json& obj, const std::string& path,
                                          const std::string& key) {
  if (!obj.contains(key)) return Err(join(path, key) + ": missing");
  const json& v = obj.at(key);
  if (!v.is_number() || !std::isfinite(v.get<double>()))
    return Err(join(path, key) + ": expected a number");
  return v.get<double>();
}

std::expected<std::string, std::string> string(const json& obj, const std::string& path,
                                               const std::string& key) {
  if (!obj.contains(key)) return Err(join(path, key) + ": missing");
  const json& v = obj.at(key);
  if (!v.is_string() || v.get<std::string>().empty())
    return Err(join(path, key) + ": expected a non-empty string");
  return v.get<std::string>();
}

std::filesystem::path resolve(const std::filesystem::path& base, const std::string& p) {
  std::filesystem::path path(p);
  return path.is_absolute() ? path : base / path;
}

}  // namespace

std::expected<DaemonConfig, std::string> parse_daemon_config(const json& j,
                                                             const std::filesystem::path& base_dir) {
  if (!j.is_object()) return Err("configuration: expected a JSON object");
  if (auto ok = only_keys(j, "", config_fields::kTopKeys);
      !ok)
    return Err(ok.error());
  DaemonConfig c;
  c.source = j;
  c.file_json = j;

  if (j.contains("plant")) {
    auto p = parse_plant_config(j["plant"]);
    if (!p) return Err(p.error());
    c.plant = std::move(*p);
    // The connection string may hold a password: it is not copied into every run.
    c.source["plant"].erase("conninfo");
  }
  if (j.contains("rate_table")) {
    // The drivers' own parser: an unknown kind or a bad field is refused naming it
    // ("rate_table.kind: unknown rate table kind 'x' (known: acutrol)").
    nlohmann::json table = j["rate_table"];
    if (table.is_object() && table.contains("status_tolerance")) {
      const auto& v = table["status_tolerance"];
      if (!v.is_number_integer() || v.get<std::int64_t>() < 1 || v.get<std::int64_t>() > 3600)
        return Err("rate_table.status_tolerance: expected an integer 1..3600 (status reads in a row), got " + v.dump());
      c.rate_table_status_tolerance = static_cast<int>(v.get<std::int64_t>());
      table.erase("status_tolerance");
    }
    auto t = drivers::parse_rate_table_config(table, "rate_table");
    if (!t) return Err(t.error().message);
    c.rate_table = std::move(*t);
  }
  if (j.contains("simulated")) {
    if (!j["simulated"].is_boolean()) return Err("simulated: expected true or false");
    c.simulated = j["simulated"].get<bool>();
  }
  if (j.contains("sim_clock")) {
    if (!j["sim_clock"].is_string() || j["sim_clock"].get<std::string>().empty())
      return Err("sim_clock: expected the path of fogbench-sim's control socket");
    if (!c.simulated) return Err("sim_clock: only with \"simulated\": true (a real chamber keeps real time)");
    c.sim_clock = resolve(base_dir, j["sim_clock"].get<std::string>());
  }

  if (j.contains("station")) {
    // Recorded with every run (its identity) and printed on certificates.
    const json& st = j["station"];
    if (!st.is_object()) return Err("station: expected an object {\"id\": ...}");
    if (auto ok = only_keys(st, "station", config_fields::kStationKeys); !ok) return Err(ok.error());
    if (st.contains("id")) {
      auto id = string(st, "station", "id");
      if (!id) return Err(id.error());
      // The same rule as every stored name (storage/identity.hpp): printable UTF-8, bounded.
      if (auto why = storage::check_stored_text("station.id", *id, storage::kMaxNameBytes); !why.empty())
        return Err(why);
      c.station_id = *id;
    }
  }

  if (!j.contains("storage") || !j["storage"].is_object())
    return Err("storage: expected an object {\"path\": ...}");
  {
    const json& s = j["storage"];
    if (auto ok = only_keys(s, "storage", config_fields::kStorageKeys); !ok) return Err(ok.error());
    auto path = string(s, "storage", "path");
    if (!path) return Err(path.error());
    c.storage_path = *path == ":memory:" ? std::filesystem::path(*path) : resolve(base_dir, *path);
    if (s.contains("synchronous")) {
      const json& v = s["synchronous"];
      if (v == "full") c.storage_synchronous_full = true;
      else if (v == "normal") c.storage_synchronous_full = false;
      else return Err("storage.synchronous: expected \"full\" or \"normal\"");
    }
    if (s.contains("size_limit_bytes") && !s["size_limit_bytes"].is_null()) {
      const json& v = s["size_limit_bytes"];
      if (!v.is_number_integer() || v.get<long long>() < 65536)
        return Err("storage.size_limit_bytes: expected an integer >= 65536");
      c.storage_size_limit_bytes = v.get<long long>();
    }
  }

  // The station's signing key (docs/daemon.md "The station key"): beside the store unless
  // signing.key_path says where; none on disk for a store in memory (a key for the process only).
  if (j.contains("signing")) {
    const json& sg = j["signing"];
    if (!sg.is_object()) return Err("signing: expected an object {\"key_path\": ...}");
    if (auto ok = only_keys(sg, "signing", config_fields::kSigningKeys); !ok) return Err(ok.error());
    if (sg.contains("key_path")) {
      auto kp = string(sg, "signing", "key_path");
      if (!kp) return Err(kp.error());
      if (kp->empty() || kp->ends_with(".pub")) return Err("signing.key_path: expected the private key's file (its public key goes beside it, as .pub)");
      c.signing_key_path = resolve(base_dir, *kp);
    }
  }
  if (c.signing_key_path.empty() && c.storage_path != ":memory:")
    c.signing_key_path = c.storage_path.parent_path() / "station.key";

  if (j.contains("web") && !j["web"].is_null()) {
    auto w = parse_web_config(j["web"], base_dir);
    if (!w) return Err(w.error());
    if (w->enabled) c.web = *w;
  }

  if (j.contains("socket")) {
    const json& s = j["socket"];
    if (!s.is_object()) return Err("socket: expected an object");
    if (auto ok = only_keys(s, "socket", config_fields::kSocketKeys);
        !ok)
      return Err(ok.error());
    // The connection limits (docs/reliability.md, "Connection limits"): each a count 1..100000.
    for (auto [key, field] : {std::pair{"max_clients", &c.socket.max_clients},
                              std::pair{"unix_max_clients", &c.socket.unix_max_clients},
                              std::pair{"max_clients_per_address", &c.socket.max_clients_per_address},
                              std::pair{"max_analyses_per_address", &c.socket.max_analyses_per_address}}) {
      if (!s.contains(key) || s[key].is_null()) continue;
      const json& v = s[key];
      if (!v.is_number_integer() || v.get<long long>() < 1 || v.get<long long>() > 100000)
        return Err(std::string("socket.") + key + ": expected an integer 1..100000");
      *field = static_cast<int>(v.get<long long>());
    }
    if (s.contains("first_request_timeout_s")) {
      // null: none; a number: seconds a network connection has to send its first request.
      if (s["first_request_timeout_s"].is_null()) {
        c.socket.first_request_timeout_s.reset();
      } else {
        auto t = number(s, "socket", "first_request_timeout_s");
        if (!t) return Err(t.error());
        if (!(*t > 0) || *t > 3600)
          return Err("socket.first_request_timeout_s: expected seconds in (0, 3600], or null for none");
        c.socket.first_request_timeout_s = *t;
      }
    }
    if (s.contains("refusal_log_interval_s")) {
      auto t = number(s, "socket", "refusal_log_interval_s");
      if (!t) return Err(t.error());
      if (!(*t >= 0.1) || *t > 86400) return Err("socket.refusal_log_interval_s: expected seconds in [0.1, 86400]");
      c.socket.refusal_log_interval_s = *t;
    }
    if (s.contains("idle_timeout_s")) {
      // null: never; a number: seconds without a request before an unsubscribed client is closed.
      if (s["idle_timeout_s"].is_null()) {
        c.socket.idle_timeout_s.reset();
      } else {
        auto t = number(s, "socket", "idle_timeout_s");
        if (!t) return Err(t.error());
        if (*t <= 0) return Err("socket.idle_timeout_s: expected a positive number of seconds, or null for none");
        c.socket.idle_timeout_s = *t;
      }
    }
    if (s.contains("group")) {
      auto g = string(s, "socket", "group");
      if (!g) return Err(g.error());
      // Checked here so that a typo is a configuration error, not a socket nobody may use.
      if (::getgrnam(g->c_str()) == nullptr) return Err("socket.group: no such group: " + *g);
      c.socket.group = *g;
    }
    if (s.contains("tcp") && s.contains("tcp_port")) return Err("socket.tcp_port: give socket.tcp.port instead, not both");
    if (s.contains("tcp")) {
      const json& t = s["tcp"];
      if (!t.is_object()) return Err("socket.tcp: expected an object {\"port\", \"address\", \"token\" | \"token_file\"}");
      if (auto ok = only_keys(t, "socket.tcp", config_fields::kSocketTcpKeys); !ok)
        return Err(ok.error());
      const json& v = t.contains("port") ? t["port"] : json(nullptr);
      if (!v.is_number_integer() || v.get<long long>() < 1 || v.get<long long>() > 65535)
        return Err("socket.tcp.port: expected an integer 1..65535");
      c.socket.tcp_port = static_cast<std::uint16_t>(v.get<long long>());
      if (t.contains("address")) {
        auto a = string(t, "socket.tcp", "address");
        if (!a) return Err(a.error());
        boost::system::error_code ec;
        boost::asio::ip::make_address(*a, ec);
        if (ec) return Err("socket.tcp.address: not an IP address: " + *a);
        c.socket.tcp_address = *a;
      }
      if (t.contains("token") && t.contains("token_file"))
        return Err("socket.tcp.token: give token or token_file, not both");
      if (t.contains("token")) {
        auto tok = string(t, "socket.tcp", "token");
        if (!tok) return Err(tok.error());
        c.socket.tcp_token = *tok;
      }
      if (t.contains("token_file")) {
        auto f = string(t, "socket.tcp", "token_file");
        if (!f) return Err(f.error());
        std::ifstream in(resolve(base_dir, *f));
        std::string line;
        if (!in || !std::getline(in, line)) return Err("socket.tcp.token_file: cannot be read: " + *f);
        while (!line.empty() && (line.back() == '\r' || line.back() == ' ')) line.pop_back();
        if (line.empty()) return Err("socket.tcp.token_file: the first line is empty");
        c.socket.tcp_token = line;
      }
      // A guessable token is no protection on a port others can reach.
      if (!c.socket.tcp_token.empty() && c.socket.tcp_token.size() < 16)
        return Err("socket.tcp.token: expected at least 16 characters");
      bool allow_remote = false;
      if (t.contains("allow_remote")) {
        if (!t["allow_remote"].is_boolean()) return Err("socket.tcp.allow_remote: expected true or false");
        allow_remote = t["allow_remote"].get<bool>();
      }
      // Reads need no token: a port other hosts can reach (0.0.0.0, ::, an interface's address)
      // shows the bench to all of them, so it is asked for in so many words, and not without a
      // token that keeps control local.
      if (!boost::asio::ip::make_address(c.socket.tcp_address).is_loopback()) {
        if (!allow_remote)
          return Err("socket.tcp.address: " + c.socket.tcp_address +
                     " is not a loopback address; reads need no token, so serving other hosts needs "
                     "\"allow_remote\": true (and a token)");
        if (c.socket.tcp_token.empty())
          return Err("socket.tcp.allow_remote: a non-loopback address (" + c.socket.tcp_address +
                     ") needs a token (socket.tcp.token or token_file) for control");
      }
    }
    if (s.contains("path")) {
      auto path = string(s, "socket", "path");
      if (!path) return Err(path.error());
      c.socket.unix_path = resolve(base_dir, *path);
    }
    if (s.contains("tcp_port") && !s["tcp_port"].is_null()) {
      const json& v = s["tcp_port"];
      if (!v.is_number_integer() || v.get<long long>() < 1 || v.get<long long>() > 65535)
        return Err("socket.tcp_port: expected an integer 1..65535");
      c.socket.tcp_port = static_cast<std::uint16_t>(v.get<long long>());
    }
  }

  if (!j.contains("chamber_limits") || !j["chamber_limits"].is_object())
    return Err("chamber_limits: expected an object {\"min_c\", \"max_c\", \"max_rate_c_per_min\"}");
  {
    const json& l = j["chamber_limits"];
    if (auto ok = only_keys(l, "chamber_limits", config_fields::kChamberLimitsKeys); !ok)
      return Err(ok.error());
    auto lo = number(l, "chamber_limits", "min_c");
    if (!lo) return Err(lo.error());
    auto hi = number(l, "chamber_limits", "max_c");
    if (!hi) return Err(hi.error());
    auto rate = number(l, "chamber_limits", "max_rate_c_per_min");
    if (!rate) return Err(rate.error());
    if (*lo > *hi) return Err("chamber_limits.min_c: greater than max_c");
    if (*rate <= 0) return Err("chamber_limits.max_rate_c_per_min: expected a positive number");
    c.limits = {*lo, *hi, *rate};
  }

  {
    auto safe = number(j, "", "safe_setpoint_c");
    if (!safe) return Err(safe.error());
    if (*safe < c.limits.min_c || *safe > c.limits.max_c)
      return Err("safe_setpoint_c: outside chamber_limits");
    c.safe_setpoint_c = *safe;
  }

  {
    auto dir = string(j, "", "profile_dir");
    if (!dir) return Err(dir.error());
    c.profile_dir = resolve(base_dir, *dir);
  }

  if (j.contains("analysis")) {
    const json& a = j["analysis"];
    if (!a.is_object()) return Err("analysis: expected an object");
    if (auto ok = only_keys(a, "analysis", config_fields::kAnalysisKeys);
        !ok)
      return Err(ok.error());
    if (a.contains("terms")) {
      auto t = string(a, "analysis", "terms");
      if (!t) return Err(t.error());
      if (auto parsed = model::parse_terms(*t); !parsed)
        return Err("analysis.terms: not a term list");
      c.analysis.terms = *t;
    }
    if (a.contains("method")) {
      auto m = string(a, "analysis", "method");
      if (!m) return Err(m.error());
      if (!model::method_from_string(*m)) return Err("analysis.method: expected \"paper\" or \"joint\"");
      c.analysis.method = *m;
    }
    if (a.contains("verify_threshold")) {
      auto t = number(a, "analysis", "verify_threshold");
      if (!t) return Err(t.error());
      if (*t <= 0) return Err("analysis.verify_threshold: expected a positive number");
      c.analysis.verify_threshold = *t;
    }
    // The ranges model::VerifyOptions::validate takes, refused here with the key's name.
    for (auto [key, field, lo, hi] : {std::tuple{"verify_max_noise_factor", &c.analysis.verify_max_noise_factor, 1.0, 100.0},
                                      std::tuple{"verify_max_fail_s", &c.analysis.verify_max_fail_s, 1.0, 1e6}}) {
      if (!a.contains(key)) continue;
      auto t = number(a, "analysis", key);
      if (!t) return Err(t.error());
      if (!(*t >= lo && *t <= hi))
        return Err(std::string("analysis.") + key + ": expected a number " + (lo == 1.0 ? "1" : "") + " to " +
                   (hi == 100.0 ? "100" : "1e6"));
      *field = *t;
    }
    if (a.contains("max_iterations")) {
      const json& v = a["max_iterations"];
      if (!v.is_number_integer() || v.get<long long>() < 1 || v.get<long long>() > 1000)
        return Err("analysis.max_iterations: expected an integer 1..1000");
      c.analysis.max_iterations = v.get<int>();
    }
    if (a.contains("causal_lags")) {
      if (!a["causal_lags"].is_boolean()) return Err("analysis.causal_lags: expected true or false");
      c.analysis.causal_lags = a["causal_lags"].get<bool>();
    }
  }

  if (j.contains("link_loss")) {
    const json& l = j["link_loss"];
    if (!l.is_object()) return Err("link_loss: expected an object {\"policy\", \"tolerance_s\"}");
    if (auto ok = only_keys(l, "link_loss", config_fields::kLinkLossKeys); !ok) return Err(ok.error());
    if (l.contains("policy")) {
      const json& v = l["policy"];
      if (v == "hold") c.link_loss.policy = LinkLossConfig::Policy::hold;
      else if (v == "safe_abort") c.link_loss.policy = LinkLossConfig::Policy::safe_abort;
      else return Err("link_loss.policy: expected \"hold\" or \"safe_abort\"");
    }
    if (l.contains("tolerance_s")) {
      auto t = number(l, "link_loss", "tolerance_s");
      if (!t) return Err(t.error());
      if (*t < 0) return Err("link_loss.tolerance_s: expected a number >= 0");
      c.link_loss.tolerance_s = *t;
    }
  }

  if (j.contains("tracking")) {
    const json& t = j["tracking"];
    if (!t.is_object()) return Err("tracking: expected an object {\"max_error_c\", \"for_s\", \"frozen_s\"}");
    if (auto ok = only_keys(t, "tracking", config_fields::kTrackingKeys); !ok) return Err(ok.error());
    for (auto [key, out] : {std::pair{"max_error_c", &c.tracking.max_error_c},
                            std::pair{"for_s", &c.tracking.for_s}, std::pair{"frozen_s", &c.tracking.frozen_s}}) {
      if (!t.contains(key)) continue;
      auto v = number(t, "tracking", key);
      if (!v) return Err(v.error());
      if (*v <= 0) return Err(join("tracking", key) + ": expected a positive number");
      *out = *v;
    }
  }

  std::filesystem::path map_dir = base_dir;
  if (j.contains("map_dir")) {
    auto d = string(j, "", "map_dir");
    if (!d) return Err(d.error());
    map_dir = resolve(base_dir, *d);
  }
  if (!j.contains("drivers")) return Err("drivers: missing");
  auto drv = drivers::parse_drivers_config(j["drivers"], map_dir, "drivers");
  if (!drv) return Err(drv.error().message);
  if (drv->units.empty()) return Err("drivers.units: expected at least one unit");
  // A slot's default serial is stored with every run that names it and shown by status and
  // fogctl: the same rule as a serial a request gives (storage/identity.hpp).
  for (std::size_t i = 0; i < drv->units.size(); ++i)
    if (auto why = storage::check_stored_text("drivers.units[" + std::to_string(i) + "].serial", drv->units[i].serial,
                                              storage::kMaxNameBytes);
        !why.empty())
      return Err(why);
  // A profile checked against chamber_limits must not then be refused setpoint by setpoint by
  // the driver: the limits have to lie within what the driver will write.
  const auto& sp = drv->chamber.setpoint_limits_c;
  if (c.limits.min_c < sp.min_c)
    return Err("chamber_limits.min_c: below drivers.chamber.setpoint_limits_c.min (" + std::to_string(sp.min_c) + ")");
  if (c.limits.max_c > sp.max_c)
    return Err("chamber_limits.max_c: above drivers.chamber.setpoint_limits_c.max (" + std::to_string(sp.max_c) + ")");
  c.drivers = std::move(*drv);
  cap_backoff_to_tolerance(c);
  // The source is stored with every run: the token is a credential, not a setting to audit.
  if (c.source.contains("socket") && c.source["socket"].contains("tcp") && c.source["socket"]["tcp"].is_object() &&
      c.source["socket"]["tcp"].contains("token"))
    c.source["socket"]["tcp"]["token"] = "(redacted)";
  return c;
}

std::expected<DaemonConfig, std::string> load_daemon_config(const std::filesystem::path& file) {
  std::ifstream in(file);
  if (!in) return Err(file.string() + ": cannot be read");
  std::stringstream ss;
  ss << in.rdbuf();
  // The reload's parser (config_reload.cpp): a syntax error names its line and column, a bad
  // key its line, at start-up and under --check-config as on a reload.
  auto c = parse_daemon_config_text(ss.str(), std::filesystem::absolute(file).parent_path());
  if (!c) return Err(file.string() + ": " + c.error());
  return c;
}

std::chrono::milliseconds gyro_retry_delay(double time_scale) {
  constexpr double wall_ms = 1000.0;  // a second at 1x
  if (!(time_scale > 1.0)) return std::chrono::milliseconds(1000);
  return std::chrono::milliseconds(std::max<std::int64_t>(1, std::llround(wall_ms / time_scale)));
}

void cap_backoff_to_tolerance(DaemonConfig& c) {
  if (c.link_loss.policy != LinkLossConfig::Policy::hold) return;
  const auto cap_ms = static_cast<std::int64_t>(std::llround(c.link_loss.tolerance_s * 1000.0 * kBackoffShareOfTolerance));
  for (drivers::BackoffConfig* b : {&c.drivers.chamber.modbus.backoff, &c.drivers.chamber.line.backoff}) {
    b->max_ms = std::max(b->initial_ms, std::min(b->max_ms, cap_ms));
  }
}

void scale_backoff_to_clock(drivers::DriversConfig& d, double time_scale) {
  if (!(time_scale > 1.0)) return;
  for (drivers::BackoffConfig* b : {&d.chamber.modbus.backoff, &d.chamber.line.backoff, &d.thermistors.modbus.backoff}) {
    auto scale = [&](std::int64_t ms) {
      return std::max<std::int64_t>(1, std::llround(static_cast<double>(ms) / time_scale));
    };
    b->initial_ms = scale(b->initial_ms);
    b->max_ms = scale(b->max_ms);
  }
}

}  // namespace fogbench::daemon
