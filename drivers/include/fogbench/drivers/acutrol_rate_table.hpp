// The rate table when its controller is an Acutronic ACUTROL: the command set of
// acutrol_dialect.hpp, one line each way, CR LF, over TCP through the line link. Blocking calls:
// run them on a worker thread.
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "fogbench/drivers/line_link.hpp"
#include "fogbench/drivers/rate_table.hpp"

namespace fogbench::drivers {

class AcutrolRateTable final : public RateTable {
 public:
  // No I/O: the first call connects. Empty clocks: system_clock / steady_clock.
  explicit AcutrolRateTable(RateTableConfig config, WallClock wall = {}, MonotonicClock clock = {});

  // ":mode:rate" (when not in rate mode), ":demand:acceleration" (once per connection),
  // ":demand:rate" after the limits check.
  Result<void> set_rate_dps(double rate_dps) override;
  // ":mode:position", ":demand:acceleration", ":demand:position" (modulo 360 deg).
  Result<void> go_to_position_deg(double position_deg) override;
  // ":mode:rate", ":demand:rate 0": down at the configured acceleration and held at rest.
  Result<void> stop() override;
  // ":read:status", ":read:rate", ":read:position", and ":read:fault" when the word has a fault.
  Result<RateTableStatus> read_status() override;
  const RateTableLimits& limits() const noexcept override { return config_.limits; }
  std::vector<RateTableEvent> take_events() override;

  // ":interlock:reset" then ":interlock:close": clears a fault that has gone, powers the motor.
  Result<void> reset_and_close();
  // One command, its reply line; "ERR n: text" is refused (out_of_range for a limit, protocol
  // otherwise), naming the device, the command and the controller's reason.
  Result<std::string> command(const std::string& text);

  LineLink& link() noexcept { return link_; }

 private:
  Result<void> setting(const std::string& text);
  Result<void> ensure_mode(RateTableMode mode);
  Result<void> ensure_acceleration();
  std::unexpected<DriverError> refuse(ErrorCode code, std::string reason);
  void record(RateTableEvent::Kind kind, std::string reason);

  RateTableConfig config_;
  WallClock wall_;
  LineLink link_;
  std::optional<RateTableMode> mode_;  // as last commanded on this connection
  bool accel_sent_ = false;            // on this connection
  bool link_down_ = false;             // a link failure seen, no exchange since
  bool fault_seen_ = false;            // the last status had a fault
  std::vector<RateTableEvent> events_;
};

}  // namespace fogbench::drivers
