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
#include <vector>

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

// The listener and its clients, on the bench's poll() loop. The chamber's link faults apply as
// to the Modbus controller: refuse_modbus closes the listener, drop_modbus the clients,
// stall_modbus delays each reply.
class AsciiChamberServer {
 public:
  using Clock = std::chrono::steady_clock;

  AsciiChamberServer(SharedState& shared, ChamberDialect dialect, std::string host, int port)
      : shared_(shared), dialect_(dialect), host_(std::move(host)), port_(port) {}
  ~AsciiChamberServer() { close(); }
  AsciiChamberServer(const AsciiChamberServer&) = delete;
  AsciiChamberServer& operator=(const AsciiChamberServer&) = delete;

  // Port 0 becomes an ephemeral one, read back with port().
  std::expected<void, std::string> open();
  int port() const { return port_; }
  Clock::time_point watch(PollSet& set);
  void after_round(Clock::time_point now);
  void update_listener();
  void drop_clients();
  std::size_t open_clients() const;
  void close();

 private:
  struct Client {
    int fd = -1;
    std::string in;
    std::vector<std::pair<Clock::time_point, std::string>> replies;  // stalled, in order
  };
  void accept();
  void read(Client& c);
  void send(Client& c, const std::string& reply);

  SharedState& shared_;
  ChamberDialect dialect_;
  std::string host_;
  int port_;
  int listen_fd_ = -1;
  std::vector<Client> clients_;
};

}  // namespace fogbench::mock
