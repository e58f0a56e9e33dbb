// A run's samples as the store keeps them (store_samples.cpp), and the options of
// Store::export_run and Store::import_run (a run as model input).
#pragma once

#include <cstdint>
#include <limits>
#include <optional>
#include <string>

#include "fogbench/model/run.hpp"
#include "fogbench/storage/identity.hpp"
#include "fogbench/storage/runs.hpp"

namespace fogbench::storage {

inline constexpr double kNoValue = std::numeric_limits<double>::quiet_NaN();

// One second of one unit, as the daemon records it. A NaN double is stored as NULL (a signal
// not read) and read back as NaN.
struct SampleRow {
  int unit_index = 0;
  double t_s = 0;                      // s since the run's start; unique per unit
  double wall_time = kNoValue;         // unix time, s
  double setpoint_c = kNoValue;        // chamber setpoint, degC
  double chamber_c = kNoValue;         // chamber air, degC
  double gyro_dph = kNoValue;          // gyro output, deg/h
  std::optional<std::int64_t> frames;  // gyro frames received for this sample
  double t1_c = kNoValue;              // coil-centre thermistor, degC
  double t2_c = kNoValue;              // coil outer-wall thermistor, degC
  model::Phase phase = model::Phase::unknown;
  std::optional<int> step;             // profile step index
  std::uint8_t flags = 0;              // model::flag bits
  double since_power_on_s = kNoValue;  // time since the gyro's last power-on as the daemon saw
                                       // it, s; kNoValue when it did not see one
  // The daemon's live compensation of this second: gyro_dph minus the drift the unit's model
  // computed in its firmware form (model/firmware.hpp), deg/h; kNoValue when there was none
  // (no model, warming up, inputs missing; docs/daemon.md "Live compensation").
  double compensated_dph = kNoValue;
  // The rate the daemon commanded the rate table to this second, deg/s (the profile's rate
  // steps, rate_schedule.hpp); kNoValue when the run drove no table.
  double rate_in_dps = kNoValue;
  // A three-axis unit's axes 1 and 2 (y, z), deg/h (gyro_dph is axis 0, x); kNoValue for a
  // one-axis unit, and for an axis that sent nothing usable that second (flag missing).
  double gyro_y_dph = kNoValue;
  double gyro_z_dph = kNoValue;
  // A three-axis unit whose axes have their own coil thermistors: y's and z's centre and outer
  // wall, degC (t1_c, t2_c are then x's); kNoValue otherwise, and for a sensor not read that
  // second (flag missing).
  double t1_y_c = kNoValue;
  double t2_y_c = kNoValue;
  double t1_z_c = kNoValue;
  double t2_z_c = kNoValue;
};

struct ExportOptions {
  // By default the leading settle samples are left out: the run proper starts after them.
  bool include_settle = false;
};

struct ImportOptions {
  std::string serial;                 // the unit's serial (required)
  std::string profile_name = "import";
  Purpose purpose = Purpose::fit;
  std::string config_json = "{}";
  std::string profile_text;                // the profile as run, when known
  std::optional<RunIdentity> identity;     // e.g. read back from the CSV's comments
  // The unit's production lot (a CSV export's `# lot:` line, lot_from_fields), 1..64 bytes of
  // printable text; none: the run has no lot, as a run started without one.
  std::optional<std::string> lot;
};

}  // namespace fogbench::storage
