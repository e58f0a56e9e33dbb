// The mock bench's chamber controller in the ASCII dialects (Espec P300/SCP-220, Weiss/Voetsch
// SIMSERV): how each answers a command line, from the same served chamber state the Modbus
// controller shows (so the physics and the faults are one), and the TCP listener that serves
// one dialect on the chamber's port in place of Modbus. Commands and replies come from the
// drivers' dialect definitions (fogbench/drivers/chamber_dialects.hpp), never the drivers.
#pragma once

#include <chrono>
#include <expected>
#include <optional>
#include <string>
#include <string_view>

#include "line_server.hpp"
#include "poll_set.hpp"
#include "registers.hpp"
#include "shared_state.hpp"

namespace fogbench::mock {

enum class ChamberDialect { modbus, espec, simserv };
std::optional<ChamberDialect> parse_chamber_dialect(std::string_view name) noexcept;
std::string_view to_string(ChamberDialect dialect) noexcept;

// The setpoints the mock controller takes, degC: outside it answers as a real controller does
// to an out-of-range value (Espec NA:DATA OUT OF RANGE, SIMSERV -6).
inline constexpr double ascii_setpoint_min_c = -100.0, ascii_setpoint_max_c = 250.0;

// One command line (its line end stripped) in, the whole reply (with its line end) out.
// `refuse_setpoint`: the refuse_setpoint fault, every setpoint refused.
std::string answer_espec(std::string_view line, ChamberRegisters& chamber, bool refuse_setpoint);
std::string answer_simserv(std::string_view line, ChamberRegisters& chamber, bool refuse_setpoint);

// The listener and its clients, on the bench's poll() loop (a LineServer, line_server.hpp). The
// chamber's link faults apply as to the Modbus controller: refuse_modbus closes the listener,
// drop_modbus the clients, stall_modbus delays each reply.
class AsciiChamberServer {
 public:
  using Clock = LineServer::Clock;

  AsciiChamberServer(SharedState& shared, ChamberDialect dialect, std::string host, int port);

  // Port 0 becomes an ephemeral one, read back with port().
  std::expected<void, std::string> open() { return lines_.open(); }
  int port() const { return lines_.port(); }
  Clock::time_point watch(PollSet& set) { return lines_.watch(set); }
  void after_round(Clock::time_point now) { lines_.after_round(now); }
  // Follows the refuse_modbus fault: the listener closed while it is on.
  void update_listener();
  void drop_clients() { lines_.drop_clients(); }
  std::size_t open_clients() const { return lines_.open_clients(); }
  void close() { lines_.close(); }

 private:
  LineServer::Reply answer(const std::string& line);

  SharedState& shared_;
  ChamberDialect dialect_;
  LineServer lines_;
};

}  // namespace fogbench::mock
