// The rate table: what a caller needs of one (`RateTable`, an interface like `Chamber`, so no
// caller depends on one kind of controller), its configuration, its status, and the events a
// driver records (a refused rate, a link lost mid-step, a fault the table reports), each naming
// the device, the time and the reason. Opened by `kind` through rate_table_registry.hpp.
// Blocking calls: run them on a worker thread.
#pragma once

#include <nlohmann/json_fwd.hpp>

#include <chrono>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include "fogbench/drivers/config.hpp"
#include "fogbench/drivers/error.hpp"

namespace fogbench::drivers {

// What the table may do. A rate beyond max_rate_dps is refused before any I/O; the acceleration
// is the one the driver demands of the controller for every rate change.
struct RateTableLimits {
  double max_rate_dps = 500.0;     // |rate| allowed, deg/s
  double max_accel_dps2 = 100.0;   // acceleration demanded for every change, deg/s^2
};

struct RateTableConfig {
  std::string kind = "acutrol";  // the driver, in the registry (rate_table_registry.hpp)
  std::string name = "table";    // how messages and events name the device
  LineEndpoint line;
  int axis = 1;                  // the controller's axis number
  RateTableLimits limits;
};

enum class RateTableMode { off, rate, position };
std::string_view to_string(RateTableMode mode) noexcept;

struct RateTableStatus {
  RateTableMode mode = RateTableMode::off;
  double rate_dps = 0;       // actual rate, deg/s
  double position_deg = 0;   // actual position, 0..360 deg
  bool interlock_closed = false;
  bool moving = false;
  bool at_rate = false;      // rate mode and the demand reached
  bool in_position = false;  // position mode and the demand reached
  bool fault = false;
  std::string fault_text;    // the controller's text when `fault`
};

// Something the caller logs and stores with the run: refused, link_lost, link_restored, fault
// (the table reports one), fault_cleared.
struct RateTableEvent {
  enum class Kind { refused, link_lost, link_restored, fault, fault_cleared };
  Kind kind = Kind::refused;
  std::chrono::system_clock::time_point time;
  std::string device;  // "table acutrol (tcp 127.0.0.1:9888)"
  std::string reason;

  // "2026-11-28T23:59:01.123Z table acutrol (tcp 127.0.0.1:9888): fault: OVERSPEED TRIP".
  std::string to_string() const;
};
std::string_view to_string(RateTableEvent::Kind kind) noexcept;

class RateTable {
 public:
  using WallClock = std::function<std::chrono::system_clock::time_point()>;      // event times
  using MonotonicClock = std::function<std::chrono::steady_clock::time_point()>;  // backoff
  virtual ~RateTable() = default;

  // Rate mode at `rate_dps` (deg/s, signed), reached at the configured acceleration. Refused
  // (out_of_range) beyond the configured limit before any I/O, and as the controller refuses.
  virtual Result<void> set_rate_dps(double rate_dps) = 0;
  // Position mode to `position_deg` (deg, any value: taken modulo 360).
  virtual Result<void> go_to_position_deg(double position_deg) = 0;
  // Down to rest at the configured acceleration, and held there (rate mode, demand 0).
  virtual Result<void> stop() = 0;
  virtual Result<RateTableStatus> read_status() = 0;
  virtual const RateTableLimits& limits() const noexcept = 0;
  // Events since the last call, oldest first.
  virtual std::vector<RateTableEvent> take_events() = 0;
};

// {"kind": "acutrol", "name": "table", "link": {...}, "axis": 1, "max_rate_dps": 500,
// "max_accel_dps2": 100}; unknown keys refused by name.
Result<RateTableConfig> parse_rate_table_config(const nlohmann::json& value, const std::string& path);

}  // namespace fogbench::drivers
