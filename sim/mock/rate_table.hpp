// The mock bench's rate table: a single-axis table with its controller's dynamics (the rate
// reaching its demand at the acceleration limit, a small sinusoidal ripple on the actual rate,
// the position integrating the rate, position moves at a slew rate), its refusals (a rate beyond
// its limit, a motion command while a fault holds it), a fault that latches until the interlock
// is reset, and the TCP listener that answers the ACUTROL command set
// (fogbench/drivers/acutrol_dialect.hpp, never the driver). Time is simulated seconds given by
// the caller: the tests step it, the bench gives its clock. Faults come from the bench's fault
// state (faults.hpp: table_fault, drop_table).
#pragma once

#include <chrono>
#include <cstdint>
#include <expected>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include "line_server.hpp"
#include "poll_set.hpp"

namespace fogbench::mock {

struct SharedState;

struct RateTableSpec {
  double max_rate_dps = 1000.0;     // the controller refuses a larger |rate| demand, deg/s
  double max_accel_dps2 = 200.0;    // the controller refuses a larger acceleration demand, deg/s^2
  double ripple_dps = 0.002;        // amplitude of the rate ripple while moving, deg/s
  double ripple_hz = 2.0;           // its frequency, Hz
  double position_slew_dps = 20.0;  // top speed of a position move, deg/s
  double standstill_dps = 1e-4;     // below this the table is not moving, deg/s
};

class RateTableSim {
 public:
  explicit RateTableSim(RateTableSpec spec = {}) : spec_(spec), accel_dps2_(spec.max_accel_dps2) {}

  // Moves the table to simulated time `t_s` (an earlier time changes nothing).
  void advance_to(double t_s);
  double time_s() const noexcept { return t_s_; }

  // The fault condition (the mock's table_fault switch): on latches a fault (interlock opens,
  // the table brakes to rest at its acceleration limit); off lets an interlock reset clear it.
  void set_fault_condition(bool on, std::string text);

  // One command line (its line end stripped) in, the whole reply (with CR LF) out.
  std::string answer(std::string_view line);

  // What the controller would read back.
  double rate_dps() const noexcept;        // actual rate, ripple included
  double smooth_rate_dps() const noexcept { return rate_dps_; }  // without the ripple
  double position_deg() const noexcept;    // 0..360
  unsigned status_word() const noexcept;
  bool fault() const noexcept { return fault_latched_; }
  const RateTableSpec& spec() const noexcept { return spec_; }

 private:
  enum class Mode { off, rate, position };
  void step_rate(double dt_s, double target_dps, double accel_dps2);
  void step_position(double dt_s);
  double ripple_integral(double t0_s, double t1_s) const;

  RateTableSpec spec_;
  double t_s_ = 0;
  Mode mode_ = Mode::off;
  bool interlock_closed_ = true;  // as after the controller's start-up sequence
  double accel_dps2_;             // demanded acceleration, deg/s^2
  double demand_rate_dps_ = 0;
  double demand_position_deg_ = 0;
  double rate_dps_ = 0;           // smooth rate, deg/s
  double position_deg_ = 0;       // unwrapped, deg
  bool fault_condition_ = false;
  bool fault_latched_ = false;
  std::string fault_text_;
};

// The listener and its clients, on the bench's poll() loop (a LineServer, line_server.hpp); the
// table lives in the shared state (SharedState::rate_table). `now_s` gives the simulated time
// each command is answered at.
class RateTableServer {
 public:
  RateTableServer(SharedState& shared, std::string host, int port, std::function<double()> now_s);

  // Port 0 becomes an ephemeral one, read back with port().
  std::expected<void, std::string> open() { return lines_.open(); }
  int port() const { return lines_.port(); }
  // Adds the listener and clients to `set`; first closes the clients when a drop_table fault
  // has been applied since the last round.
  void watch(PollSet& set);
  void drop_clients() { lines_.drop_clients(); }
  std::size_t open_clients() const { return lines_.open_clients(); }
  void close() { lines_.close(); }

 private:
  LineServer::Reply answer(const std::string& line);

  SharedState& shared_;
  std::function<double()> now_s_;
  std::uint64_t drops_seen_ = 0;
  LineServer lines_;
};

}  // namespace fogbench::mock
