// What the mock bench's threads share, under one mutex: the served registers, the fault state
// and a status snapshot. The server loop (Modbus, control) and the clock thread (physics, CAN)
// meet only here and in the CAN bus's client list (can_bus.hpp).
#pragma once

#include <cstdint>
#include <mutex>
#include <optional>
#include <vector>

#include "faults.hpp"
#include "rate_table.hpp"
#include "registers.hpp"

namespace fogbench::mock {

struct UnitStatus {
  double t1_c = 0, t2_c = 0, true_t1_c = 0, true_t2_c = 0, gyro_dph = 0;
  std::uint64_t frames_sent = 0, frames_lost = 0, frames_corrupted = 0;
  bool powered = true;
  double powered_on_at_s = 0;  // simulated time of the gyro's last power-on, s
  // A three-axis unit's axes 1 and 2 (the fields above are axis 0's): the mean output of the
  // last second, deg/h, and their frames, both axes together.
  std::vector<double> axis_gyro_dph;
  std::uint64_t axes_frames_sent = 0, axes_frames_lost = 0, axes_frames_corrupted = 0;
};

// The bench as the last simulated second left it, for the status reply.
struct Snapshot {
  double time_s = 0, setpoint_c = 0, air_c = 0, pv_c = 0;
  bool running = true;
  std::vector<UnitStatus> units;
};

struct SharedState {
  std::mutex mutex;
  std::optional<ChamberRegisters> chamber;
  std::optional<ThermistorRegisters> thermistors;
  std::optional<RateTableSim> rate_table;  // when the bench serves one (rate_table.hpp)
  FaultState faults;
  Snapshot snap;
};

}  // namespace fogbench::mock
