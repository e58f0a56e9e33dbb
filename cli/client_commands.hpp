// What fogctl's client commands share (an internal header of cli/): the options every command
// takes to reach the daemon, the formatting of its answers, and the watch of a run (watch.cpp)
// that run start/resume --wait end in. client.hpp is the daemon client itself.
#pragma once

#include <cstdint>
#include <expected>
#include <optional>
#include <ostream>
#include <string>

#include <nlohmann/json.hpp>

#include "client.hpp"
#include "table.hpp"

namespace CLI {
class App;
}

namespace fogbench::cli::commands {

// Where the daemon is and how to print: the options of every client command.
struct Common {
  std::string socket = default_socket();
  std::string connect;  // HOST:PORT: the daemon's TCP endpoint instead of the unix socket
  std::string token = default_token();
  bool json_out = false;
};

// --socket, --connect, --token (and --json unless with_json is false).
void add_common(CLI::App* c, Common& o, bool with_json = true);
// A connection to the daemon the options name.
std::expected<Client, ClientError> open(const Common& o);
// "fogctl: [code: ]message" on err; the exit code of an error (2).
int report(const ClientError& e, std::ostream& err);

// A number with `digits` decimals, "-" for null or a value not read.
std::string num_text(const nlohmann::json& v, int digits = 2);
std::string num_text(std::optional<double> v, int digits = 2);
std::string num_text(double v, int digits = 2);
// H:MM:SS, "-" for a negative or unknown duration.
std::string duration_text(double s);
// status.plant in one line for `fogctl status`: the outbox, the link's state (STALLED in
// capitals, with the run and how long without progress) and the last error.
std::string plant_status_text(const nlohmann::json& plant);

// --operator NAME and --lot LOT | --lot SERIAL=LOT (repeatable) into a request's "operator",
// "lot" or "lots" (run start, plan start, queue add); false, with the error on err naming
// `what` ("fogctl run start"), when the name or a --lot is malformed.
bool add_operator_and_lots(nlohmann::json& req, const std::string& operator_name, const std::vector<std::string>& lots,
                           const std::string& what, std::ostream& err);
// --unit SERIAL (repeatable: a slot's configured default serial) and --slot SLOT=SERIAL
// (repeatable: the serial in that bench slot for this run) into a request's "units" and "slots"
// (run start, plan start, queue add); false, with the error on err naming `what`, when a --slot
// is malformed, a slot is given twice, or neither is given.
bool add_units_and_slots(nlohmann::json& req, const std::vector<std::string>& units,
                         const std::vector<std::string>& slots, const std::string& what, std::ostream& err);
// Per unit of a run: frames lost and corrupt, samples flagged (and samples stored when given).
Table quality_table(const nlohmann::json& serials, const nlohmann::json& quality, const nlohmann::json* samples = nullptr);
// Table 1 of a run's verifications.
void print_table1(const nlohmann::json& verifications, const nlohmann::json& run, std::ostream& out);

// A run's unit named by serial (first) or by index in the run; an error lists its units.
std::expected<int, ClientError> resolve_unit(Client& c, std::int64_t run_id, const std::string& unit);
// A run's audit trail as a table: time, kind and the detail in words (key value, ...).
Table events_table(const nlohmann::json& events);

// Whether a run state is an end (completed, aborted, failed, interrupted).
bool terminal(const std::string& state);
// The exit code of a finished run (0 completed and passed, 3 marginal, 1 a verification
// failed, 2 anything else), with its summary on out.
int final_code(Client& c, std::int64_t run_id, std::ostream& out, bool json_out);
// Follows a run (the active one when run_id is empty) to its end, reconnecting for up to
// reconnect_s when the daemon goes away; progress on err unless quiet. raw: the run's sample and
// event messages on out as NDJSON instead of the progress and the summary.
int watch(const Common& o, std::optional<std::int64_t> run_id, bool quiet, double reconnect_s, std::ostream& out,
          std::ostream& err, bool raw = false);

}  // namespace fogbench::cli::commands
