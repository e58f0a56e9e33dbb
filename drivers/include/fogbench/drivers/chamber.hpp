// The thermal chamber: what the daemon needs of one (`Chamber`, an interface like the CAN
// transports' CanTransport, so the daemon depends on no one kind of controller), and the
// controller over Modbus (TCP or RTU) addressed through a register map from configuration
// (`ModbusChamber`). Blocking calls: the daemon runs them on a worker thread.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "fogbench/drivers/config.hpp"
#include "fogbench/drivers/error.hpp"
#include "fogbench/drivers/modbus_link.hpp"

namespace fogbench::drivers {

struct ChamberStatusWord {
  std::uint32_t raw = 0;
  std::vector<std::pair<std::string, bool>> bits;  // the map's named bits, in map order
};

// One poll of everything the daemon records each second.
struct ChamberReading {
  double process_value_c = 0;
  double setpoint_c = 0;
  bool running = false;
  bool alarm = false;
  std::optional<ChamberStatusWord> status;  // when the map has a status register
};

struct BringUpCheck {
  std::string name;    // "identity", "units", "process_value", "alarm", ...
  bool ok = false;
  std::string detail;  // what was read and what was expected
};

// What a bring-up found. A check that fails is a finding, not an error: the report is returned
// whole so the operator sees every problem at once.
struct BringUpReport {
  std::vector<BringUpCheck> checks;

  bool ok() const noexcept;
  // One line per check: "ok   identity: 61618 (expected 61618)".
  std::string to_string() const;
};

// What the daemon asks of a chamber: bring it up, command its setpoint and run state, poll it.
// Every call blocks until the controller answered or failed (a link error, a refused value).
class Chamber {
 public:
  virtual ~Chamber() = default;

  // Checks what can be checked before a run (identity, units, plausible readings). Returns an
  // error only when the chamber cannot be reached; everything else is in the report.
  virtual Result<BringUpReport> bring_up() = 0;
  // Refuses (out_of_range) a setpoint outside the configured limits before any I/O.
  virtual Result<void> write_setpoint_c(double temp_c) = 0;
  virtual Result<void> set_running(bool run) = 0;
  // Everything the daemon records each second.
  virtual Result<ChamberReading> poll() = 0;
};

// The chamber's controller over Modbus.
class ModbusChamber final : public Chamber {
 public:
  // No I/O: the first call connects. An empty clock means steady_clock::now (tests inject one
  // to walk the reconnection backoff).
  explicit ModbusChamber(ChamberConfig config, ModbusLink::Clock clock = {});

  // Refuses (out_of_range) a setpoint outside setpoint_limits_c before any I/O.
  Result<void> write_setpoint_c(double temp_c) override;
  Result<double> read_setpoint_c();
  Result<double> read_process_value_c();
  Result<void> set_running(bool run) override;
  Result<bool> read_running();
  Result<bool> read_alarm();
  // `config` error when the map has no status register.
  Result<ChamberStatusWord> read_status();
  Result<ChamberReading> poll() override;

  // Connects, reads identity and units where the map has them (comparing with their expected
  // values), the process value (within pv_limits_c), the setpoint, the alarm and the status.
  Result<BringUpReport> bring_up() override;

  const ChamberConfig& config() const noexcept { return config_; }
  ModbusLink& link() noexcept { return link_; }

 private:
  ChamberConfig config_;
  ModbusLink link_;
};

}  // namespace fogbench::drivers
