// The chamber's controller when it is a Weiss or Voetsch chamber on SIMSERV: numbered commands
// (11001/11002 setpoint, 11004 actual value, 14001 start/stop, 10012 status, 99997 type), fields
// separated by 0xB6, CR-terminated, over TCP (port 2049 by default). Blocking calls: the daemon
// runs them on a worker thread.
#pragma once

#include <string>
#include <vector>

#include "fogbench/drivers/chamber.hpp"
#include "fogbench/drivers/line_link.hpp"

namespace fogbench::drivers {

class SimservChamber final : public Chamber {
 public:
  // No I/O: the first call connects. An empty clock means steady_clock::now.
  explicit SimservChamber(ChamberConfig config, LineLink::Clock clock = {});

  Result<BringUpReport> bring_up() override;
  // 11001 after the limits check; a reply whose first field is not 1 is refused (protocol),
  // naming the command and the reply.
  Result<void> write_setpoint_c(double temp_c) override;
  // 14001 with 1 (start the manual mode) or 0 (stop).
  Result<void> set_running(bool run) override;
  // 11004 (actual value), 11002 (setpoint), 10012 (status: running, warnings, alarms).
  Result<ChamberReading> poll() override;

  // One command and its reply's values; a first field other than 1 is a `protocol` error.
  Result<std::vector<std::string>> query(int number, std::vector<std::string> args);

  LineLink& link() noexcept { return link_; }

 private:
  Result<double> read_number(int number, std::vector<std::string> args);
  Result<ChamberStatusWord> read_status();

  ChamberConfig config_;
  LineLink link_;
};

}  // namespace fogbench::drivers
