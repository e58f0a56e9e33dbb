// What the acquisition hands the station each second (acquisition.hpp in daemon/src): the gyro
// bus's sample of every unit, the chamber's and the thermistor module's latest readings, and
// what was missing or late. Its own header, so that what builds or reads a second (the
// acquisition, sample_rows, the tests' fake benches) does not include the station.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace fogbench::daemon {

// One axis of a three-axis unit beyond its first (drivers::BusSample::extra_axes).
struct AxisReading {
  std::optional<double> rate_dph;  // deg/h; empty: no usable frame this period
  std::uint32_t frames = 0;
  std::uint32_t frames_lost = 0;
  std::uint32_t frames_corrupt = 0;
  std::uint32_t frames_saturated = 0;  // counts at the int32 limit: the rate is clipped
};

// One configured unit's readings at one tick; an empty optional was not read.
struct UnitReading {
  std::optional<double> gyro_dph;
  std::uint32_t frames = 0;
  std::uint32_t frames_lost = 0;
  std::uint32_t frames_corrupt = 0;  // bad CRC or length: discarded, so lost to the average too
  std::uint32_t gyro_starts = 0;     // frames that began a power-on (drivers::GyroSample::starts)
  // Averaged frames whose counts were at the int32 limit (drivers::GyroSample::frames_saturated):
  // the rate beyond what the unit's scale carries, so gyro_dph is clipped.
  std::uint32_t frames_saturated = 0;
  std::optional<double> t1_c;  // with thermistors per axis: x's
  std::optional<double> t2_c;
  // A three-axis unit whose axes have their own coil thermistors (drivers::UnitConfig::
  // axis_thermistors): y's and z's centre and outer wall, [0] y and [1] z, each empty where the
  // sensor could not be read; both vectors empty for a unit whose axes share t1_c, t2_c.
  std::vector<std::optional<double>> axis_t1_c, axis_t2_c;
  bool out_of_range = false;  // a sensor or the gyro reported a value outside its range
  // A three-axis unit's axes 1 and 2 (y, z) when the bus was read; empty for a one-axis unit
  // (gyro_dph and the frame counts above are axis 0's, x).
  std::vector<AxisReading> extra_axes;
};

// The rate table as its worker last saw it (rate_table_link.hpp): at its last command or status
// read, each naming the device.
struct RateTableReading {
  bool link_down = false;  // the table did not answer (reason says why)
  bool fault = false;      // the table reports a fault (reason: its text)
  // Its status reads failed, for a reason other than the link (a garbled reply), as many times
  // in a row as rate_table.status_tolerance allows (reason: how many, and the last reply).
  bool unreadable = false;
  std::string reason;
};

// Everything read in one acquisition period.
struct TickInput {
  double wall_time = 0.0;                    // unix time, s
  std::optional<double> chamber_c;           // process value (air)
  std::optional<double> chamber_setpoint_c;  // as read back from the controller
  bool chamber_alarm = false;
  bool chamber_link_down = false;            // the chamber could not be polled this period
  std::vector<UnitReading> units;            // one per configured unit, in config order
  // The loop was too late for this second (a busy host at a high time scale): what is missing
  // is missing for that, not for a fault. A run that fails after such seconds says so.
  bool late = false;
  // The gyro bus was read for this period (false: its link down, the loop late, a paced bench
  // that did not step).
  bool gyro_read = true;
  // The gyro bus was connected through this period. A loop that is late loses no frame (they wait
  // in the socket and are read later, their counter intact); a link down does, and a gyro's whole
  // start-up could be among them (PowerWatch, power_on.hpp).
  bool gyro_link_up = true;
  // What the gyro's transport found wrong in its stream since the last period (a serial line's
  // garbage, CRC errors, cut frames, a silence that looks like a wrong baud rate), each line
  // naming the device, already limited to a line a minute per kind of problem (RepeatLogSet):
  // the station records each as a `fault` event of the run.
  std::vector<std::string> gyro_stream_events;
  // The rate table, when one is configured (the server's wiring adds it to each second; none:
  // no table). A run with rate steps ends aborted on its fault or its link's loss.
  std::optional<RateTableReading> rate_table;
};

// Told after every second the station has ticked (the plan runner, plan_runner.hpp): the station
// calls its listeners, never the runner itself.
class TickListener {
 public:
  virtual ~TickListener() = default;
  // After the station's tick of daemon time `clock_s` (s), read at `wall_time` (unix s).
  virtual void after_tick(double clock_s, double wall_time) = 0;
};

}  // namespace fogbench::daemon
