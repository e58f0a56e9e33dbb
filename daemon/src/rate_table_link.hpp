// The rate table's side of the daemon (issue 29): the configured table (rate_table_registry.hpp)
// on a worker thread of its own, as the chamber is on the acquisition's device worker, so that
// its blocking I/O never runs on the loop. Each second the server's wiring hands it the rate the
// station commands (TickOutput::rate_dps) and gives the next second the table's state as last
// seen (TickInput::rate_table). A command the table refused is sent again the next second.
#pragma once

#include <functional>
#include <memory>
#include <string>

#include "fogbench/daemon/tick_input.hpp"
#include "fogbench/drivers/rate_table.hpp"

namespace boost::asio {
class io_context;
}

namespace fogbench::daemon {

class RateTableLink {
 public:
  // `table`: opened from the configuration; its calls run on this link's worker only.
  // `status_tolerance`: the status reads in a row that may fail for a reason other than the link
  // (a garbled reply, one the driver cannot read) before reading() says `unreadable` (>= 1).
  RateTableLink(boost::asio::io_context& loop, std::unique_ptr<drivers::RateTable> table, int status_tolerance = 5);
  ~RateTableLink();  // runs the jobs queued (the stop of stop_table) and joins the worker
  RateTableLink(const RateTableLink&) = delete;
  RateTableLink& operator=(const RateTableLink&) = delete;

  // On the loop, each second: the table to `rate_dps` (deg/s; 0: stop()) unless it is there
  // already, then its status read; skipped while the last second's job is still under way.
  void command(double rate_dps);
  // On the loop: the table's state from the last job done. A failed status read that is not
  // the link's is the last read's reason alone (no fault, no link_down) until
  // `status_tolerance` of them in a row make it `unreadable`; a good read starts the count
  // again.
  RateTableReading reading() const { return reading_; }
  // On the loop, at the daemon's stop: the table stopped (rate 0) on the worker, whatever was
  // commanded; `done` on the loop with the error ("" when stopped).
  void stop_table(std::function<void(const std::string& error)> done);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  RateTableReading reading_;
};

}  // namespace fogbench::daemon
