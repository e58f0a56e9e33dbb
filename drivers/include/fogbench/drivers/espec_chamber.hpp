// The chamber's controller when it is an Espec P300 or SCP-220: the ASCII command set (TEMP?,
// MON?, MODE?, ALARM?, TYPE?; "TEMP, S<degC>", "MODE, CONSTANT|STANDBY"), one line each way,
// CR LF, over TCP or a serial port. Blocking calls: the daemon runs them on a worker thread.
#pragma once

#include <string>
#include <string_view>

#include "fogbench/drivers/chamber.hpp"
#include "fogbench/drivers/chamber_dialects.hpp"
#include "fogbench/drivers/line_link.hpp"

namespace fogbench::drivers {

class EspecChamber final : public Chamber {
 public:
  // No I/O: the first call connects. An empty clock means steady_clock::now.
  explicit EspecChamber(ChamberConfig config, LineLink::Clock clock = {});

  Result<BringUpReport> bring_up() override;
  // "TEMP, S<degC>" after the limits check; an NA: reply is refused (out_of_range for
  // DATA OUT OF RANGE, protocol otherwise), naming the command and the reply.
  Result<void> write_setpoint_c(double temp_c) override;
  // "MODE, CONSTANT" to run at the setpoint, "MODE, STANDBY" to stop controlling.
  Result<void> set_running(bool run) override;
  // TEMP? (process value, setpoint) and MON? (mode, alarm count).
  Result<ChamberReading> poll() override;

  // One command, its reply line; an NA: reply is a `protocol` error naming both.
  Result<std::string> query(std::string_view command);

  LineLink& link() noexcept { return link_; }

 private:
  Result<espec::TempReply> read_temp();
  Result<espec::MonReply> read_mon();
  Result<void> setting(const std::string& command, ErrorCode refused);
  std::unexpected<DriverError> unexpected_reply(std::string_view command, const std::string& reply,
                                                std::string_view expected);

  ChamberConfig config_;
  LineLink link_;
};

}  // namespace fogbench::drivers
