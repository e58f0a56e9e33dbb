// fogbenchd's configuration file: the bench's drivers, storage, command socket, chamber limits,
// safe setpoint, profile directory and analysis defaults. Every refusal names the field
// ("chamber_limits.max_c: expected a number"). The shape is documented in docs/daemon.md.
#pragma once

#include <chrono>
#include <cstdint>
#include <expected>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "fogbench/drivers/config.hpp"
#include "fogbench/drivers/rate_table.hpp"
#include "fogbench/model/noise.hpp"
#include "fogbench/profiles/profile.hpp"

namespace fogbench::daemon {

struct SocketConfig {
  std::filesystem::path unix_path = "/run/fogbench/fogbenchd.sock";
  std::optional<std::string> group;       // the unix socket's group (mode 0660); the daemon's own when empty
  std::optional<std::uint16_t> tcp_port;  // TCP is off unless given
  std::string tcp_address = "127.0.0.1";  // loopback unless configured otherwise
  // Control commands over TCP need a request field `token` equal to this (from socket.tcp.token
  // or the first line of socket.tcp.token_file); empty: TCP only reads.
  std::string tcp_token;
  // Network connections open at once: TCP and the web side (HTTP and WebSocket) together; one
  // more gets an error line (the web: 503) and is closed. The unix socket is not counted here.
  int max_clients = 256;
  // The unix socket's own share, on top of max_clients: network clients never take it.
  int unix_max_clients = 64;
  // Network connections (TCP and web together) from one remote address at once.
  int max_clients_per_address = 32;
  // Analysis requests (fits, the workbench, large reads: the commands the analysis worker
  // answers) waiting or running at once from one network address; one more gets `busy`. The
  // unix socket has no such limit, and its requests are served before the network's.
  int max_analyses_per_address = 4;
  // A TCP connection that sends no whole request line this long after its hello (wall seconds),
  // or a web request that has not arrived whole this long after the connection opened or the
  // last answer, is closed. None when empty. The unix socket has none.
  std::optional<double> first_request_timeout_s = 10.0;
  // Refused connections are logged at most once per this (wall seconds), with their count.
  double refusal_log_interval_s = 60.0;
  // A client that is not subscribed and sends nothing this long (wall seconds) is closed; none
  // when empty. Subscribers only listen, so they are never idle.
  std::optional<double> idle_timeout_s = 600.0;
};

// The web panel and metrics (docs/web.md): off unless configured. Loopback unless allow_remote.
struct WebConfig {
  std::string address = "127.0.0.1";
  std::uint16_t port = 8080;  // 0: the kernel picks (reported in the ready line's web_port)
  bool allow_remote = false;  // a non-loopback address is refused unless true
  bool enabled = true;        // `enabled: false`: the section is checked, nothing is served
  // The web side's control token: the first line of web.token_file (relative to the
  // configuration's folder); empty: socket.tcp's token, if any.
  std::string token;
  // The DNS names by which browsers reach the panel (web.hosts, lower case), beside an IP
  // address and `localhost`, which are always accepted: a request for /ws, /api or /metrics whose
  // Host (or Origin) names anything else is refused, so that a page that rebinds its own name to
  // this address (DNS rebinding) cannot read the bench.
  std::vector<std::string> hosts;
};
// Whether a request's Host header ("name", "name:port", "[v6]:port"; empty when absent) names
// this panel: an IP address, `localhost`, or one of `hosts`, in any case.
bool web_host_allowed(const WebConfig& w, std::string_view host_header);
// Whether a request's Origin header may reach the panel: absent (not a browser), or
// "scheme://host[:port]" whose host[:port] is the request's Host and whose host is allowed.
bool web_origin_allowed(const WebConfig& w, std::string_view origin, std::string_view host_header);
// Parses the `web` section ({listen: "host:port", allow_remote?, enabled?, token_file?}); errors
// name the field. A relative token_file is relative to base_dir; it is read only when enabled.
std::expected<WebConfig, std::string> parse_web_config(const nlohmann::json& j,
                                                       const std::filesystem::path& base_dir = {});

struct AnalysisConfig {
  std::string terms = "paper";    // term list of automatic fits (model/terms.hpp)
  std::string method = "paper";   // paper | joint
  double verify_threshold = 0.2;  // compensated/raw std ratio a verification must stay under
  // The verdict's second test (model::NoiseRule, the one rule verify, compare and diagnose
  // share): a run whose ratio passes is `marginal` when its compensated std exceeds this many
  // times the gyro's noise floor ...
  double verify_max_noise_factor = model::NoiseRule{}.max_noise_factor;
  // ... or when it has a failing interval (61 s average of the residual beyond 3 sigma_a) this
  // long or longer, s.
  double verify_max_fail_s = 60.0;
  int max_iterations = 30;  // joint method: Cochrane-Orcutt iterations at most
  // true: automatic lags held at what the firmware form can meet (model::FitOptions::causal_lags:
  // 30 s per d(), 60 s per dd()), so every model the station fits gets a firmware form and live
  // compensation. false (default, as before): the paper's unconstrained lags, whose coefficients
  // are the physical ones a plan's `sensitivity` limit judges; a rate term at lag 0 then has no
  // firmware form (docs/firmware.md). Held lags move the coefficients (on the mock bench's unit
  // with a static T1 effect d(T1) went from within +-20 to 40): a serial's physical model and its
  // firmware model are two fits, which issue 24's one verdict has to keep apart.
  bool causal_lags = false;
};

// What a run does while the chamber cannot be polled (docs/daemon.md, "Faults").
struct LinkLossConfig {
  enum class Policy { hold, safe_abort };
  // hold: the profile clock stops and the last setpoint stands until the link is back; a gap
  // longer than tolerance_s aborts the run. safe_abort: the run is aborted when the link is lost.
  Policy policy = Policy::hold;
  double tolerance_s = 60.0;
};

// When a chamber that does not follow its setpoint aborts the run.
struct TrackingConfig {
  double max_error_c = 5.0;  // |PV - setpoint| above this ...
  double for_s = 600.0;      // ... for this long (running state only: a settle has its own timeout)
  double frozen_s = 300.0;   // the PV exactly unchanged this long while the setpoint moves
};

// The plant store (issue 14, docs/plant.md): completed runs are replicated to PostgreSQL from an
// outbox in the bench's store. Absent: no outbox is written and nothing is sent.
struct PlantConfig {
  std::string conninfo;        // libpq connection string or URI ("service=plant", "host=... dbname=...")
  std::string bench_id;        // this bench's name in the plant, 1..64 characters
  double poll_s = 2.0;         // how often the outbox is looked at when idle, wall s
  double retry_max_s = 60.0;   // the longest wait between failed attempts (doubling from 1 s), wall s
  double stall_s = 30.0;       // a connection or run's transaction this long without progress is "stalled", wall s
  int connect_timeout_s = 10;  // one connection attempt's bound (libpq connect_timeout) unless conninfo sets one, wall s
};

struct DaemonConfig {
  bool simulated = false;                  // --time-scale is refused unless true
  std::filesystem::path storage_path;      // the SQLite store
  bool storage_synchronous_full = true;    // fsync every commit (see storage's OpenOptions)
  std::optional<std::int64_t> storage_size_limit_bytes;  // the store never grows past it (disk_full)
  SocketConfig socket;
  std::optional<WebConfig> web;            // the web panel; off when empty
  profiles::ChamberLimits limits;
  double safe_setpoint_c = 20.0;
  std::filesystem::path profile_dir;
  AnalysisConfig analysis;
  LinkLossConfig link_loss;
  TrackingConfig tracking;
  drivers::DriversConfig drivers;
  // Simulated benches only: fogbench-sim's control socket. The daemon then paces the simulated
  // world (fogbench-sim --paced): one {"cmd":"advance"} per acquired second of a run, so a busy
  // host slows a run down instead of breaking it (docs/daemon.md, "Time scale").
  std::optional<std::filesystem::path> sim_clock;
  std::string station_id;                  // station.id: recorded in every run's identity ("" when unset)
  // signing.key_path: the station's Ed25519 key, created at the first start (mode 0600), its
  // public key beside it as .pub. Default: station.key beside the store; empty for a store in
  // memory (a key made for the process alone).
  std::filesystem::path signing_key_path;
  std::optional<PlantConfig> plant;        // replication to the plant store; none when absent
  // The rate table (`rate_table`, drivers/rate_table.hpp: kind, name, link, axis, max_rate_dps,
  // max_accel_dps2), driven by the profiles' rate steps; none: a profile with rate steps is refused.
  std::optional<drivers::RateTableConfig> rate_table;
  // rate_table.status_tolerance: the table's status reads in a row that may fail for a reason
  // other than its link (a garbled reply) before a run that drives it is aborted (1..3600; one
  // read a second). Read by the daemon, not the drivers' parser.
  int rate_table_status_tolerance = 5;
  nlohmann::json source;                   // the file as read, stored with every run (plant.conninfo left out)
  // The file as read, nothing left out: what a reload compares the new file with (never stored).
  nlohmann::json file_json;
};

// The `plant` section (config_plant.cpp).
std::expected<PlantConfig, std::string> parse_plant_config(const nlohmann::json& j);

// Parses the configuration; relative paths are resolved against base_dir (the file's folder).
std::expected<DaemonConfig, std::string> parse_daemon_config(const nlohmann::json& j,
                                                             const std::filesystem::path& base_dir);
// The drivers' reconnection backoff (drivers.*.modbus.backoff) counts wall time. On the
// accelerated clock (--time-scale K, simulated benches) its delays are divided by K, so a lost
// link is retried after the same run time as at 1x: the default 30 s cap is 30 s of run time,
// not 30 s of wall time (25 min of run time at 50x). Never below 1 ms; K <= 1 changes nothing.
void scale_backoff_to_clock(drivers::DriversConfig& drivers, double time_scale);

// A chamber outage shorter than link_loss.tolerance_s must be survived (issue 27, point 4): the
// run is aborted when the link has been down longer than the tolerance, and a reconnection is
// only tried when the back-off's delay has run out, so the delay may never grow past a tenth of
// the tolerance (60 s: at most 6 s between attempts; before, 30 s made the real tolerance about
// 32 s). Applied by parse_daemon_config to the chamber's back-off (modbus and link) under the
// `hold` policy; never below initial_ms. An outage up to 0.9 x tolerance_s, less one
// response_timeout_ms, is then survived.
inline constexpr double kBackoffShareOfTolerance = 0.1;
void cap_backoff_to_tolerance(DaemonConfig& config);

// The gyro bus is reopened this long after it fails: a second of run time, i.e. 1 s of wall
// time divided by the time scale on the accelerated clock (never below 1 ms).
std::chrono::milliseconds gyro_retry_delay(double time_scale);

// Reads and parses a file; errors start with the file name.
std::expected<DaemonConfig, std::string> load_daemon_config(const std::filesystem::path& file);

}  // namespace fogbench::daemon
