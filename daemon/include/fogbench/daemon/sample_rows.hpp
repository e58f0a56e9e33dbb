// One second of a run as stored and as pushed: the pure half of the station's tick. The readings
// of one period, the profile's state and the run's units in, one storage row per unit out (with
// its quality flags), and the `sample` message of each. No store, no clock: tested alone
// (tests/daemon/sample_rows_test.cpp).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "fogbench/profiles/executor.hpp"
#include "fogbench/protocol/protocol.hpp"
#include "fogbench/storage/runs.hpp"
#include "fogbench/storage/samples.hpp"

namespace fogbench::daemon {

struct TickInput;
struct UnitReading;

// Readings outside these are implausible for a coil or a gyro on a drift bench (flag out_of_range).
// On a rate table the gyro reads the table's rate besides its drift: its bound is
// kGyroMaxAbsDph plus the largest rate the run commands (in deg/h), whatever the table is doing
// that second (it ramps between steps at its own acceleration).
inline constexpr double kCoilMinC = -100.0, kCoilMaxC = 200.0;
inline constexpr double kGyroMaxAbsDph = 1.0e5;

// The quality bits (model::flag) of one unit's second: missing (a reading absent), frames_lost,
// out_of_range, link_gap (the chamber could not be polled), pv_frozen (the chamber's PV is stale).
// table_max_abs_dps: the largest |rate| the run commands its rate table, deg/s (0: no table).
std::uint8_t quality_flags(const UnitReading& u, const TickInput& in, bool pv_frozen, double table_max_abs_dps = 0.0);

// One unit's row of a second at run time t_s: the setpoint recorded is the profile's for this
// second; a value not read is NaN.
storage::SampleRow sample_row(int unit_index, const UnitReading& u, const TickInput& in, double t_s,
                              const profiles::ExecutorStatus& st, bool pv_frozen,
                              std::optional<double> since_power_on_s, double table_max_abs_dps = 0.0);

// The `sample` message of a stored row, for subscribers; a unit of 3 `axes` with its y and z.
protocol::SampleMessage sample_message(const storage::SampleRow& r, std::int64_t run_id, const std::string& serial,
                                       storage::RunState state, const profiles::ExecutorStatus& st,
                                       std::optional<double> chamber_c, int axes = 1);

}  // namespace fogbench::daemon
