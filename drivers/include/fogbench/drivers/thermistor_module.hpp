// The coil thermistors (T1 centre, T2 outer wall) of every unit under test: what the daemon
// asks of them (`ThermistorSource`) and the Modbus input module that reads them. Blocking, like
// the chamber: the daemon runs it on a worker thread.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "fogbench/drivers/config.hpp"
#include "fogbench/drivers/error.hpp"
#include "fogbench/drivers/modbus_link.hpp"

namespace fogbench::drivers {

// A sensor that cannot be read (open circuit, short, out of range, refused by the module) is an
// error value naming the unit and the sensor, never a number.
struct CoilTemperatures {
  std::string serial;
  Result<double> t1_c;  // coil centre (a unit with thermistors per axis: x's)
  Result<double> t2_c;  // coil outer wall (idem)
  // A three-axis unit with thermistors per axis (UnitConfig::axis_thermistors): y's and z's coil
  // centre and outer wall, [0] y and [1] z; empty when its axes share t1_c, t2_c.
  std::vector<Result<double>> axis_t1_c = {}, axis_t2_c = {};
};

// What the daemon needs of the coil thermistors: every unit's two sensors, in unit order. An
// interface like Chamber, so the daemon depends on no one kind of input module and a test can
// hand it a fake.
class ThermistorSource {
 public:
  virtual ~ThermistorSource() = default;
  // A link failure fails the whole call; a sensor that cannot be read fails only itself.
  virtual Result<std::vector<CoilTemperatures>> read_all() = 0;
};

// The Modbus input module.
class ThermistorModule final : public ThermistorSource {
 public:
  ThermistorModule(ThermistorModuleConfig config, std::vector<UnitConfig> units,
                   ModbusLink::Clock clock = {});

  // Reads every unit's two sensors (six with thermistors per axis), in unit order. Contiguous registers go in one request. A
  // link failure (timeout, connection) fails the whole call; a request the module refuses fails
  // only the sensors it covers.
  Result<std::vector<CoilTemperatures>> read_all() override;

  // Requests one read_all() makes (for the operator: fewer is better on a slow RTU line).
  std::size_t request_count() const noexcept { return blocks_.size(); }
  ModbusLink& link() noexcept { return link_; }

 private:
  struct Sensor {
    std::size_t unit = 0;
    int which = 1;         // 1 or 2
    std::size_t axis = 0;  // 0: the unit's t1, t2 (x's); 1 y, 2 z: UnitConfig::axis_thermistors
    std::size_t block = 0;
    std::size_t offset = 0;  // of its first word in the block
  };
  struct Block {
    RegisterFunction function = RegisterFunction::input;
    std::uint16_t address = 0;
    std::uint16_t count = 0;
  };
  const ThermistorChannelConfig& channel(const Sensor& s) const;

  ThermistorModuleConfig config_;
  std::vector<UnitConfig> units_;
  ModbusLink link_;
  std::vector<Sensor> sensors_;
  std::vector<Block> blocks_;
};

// The coil thermistors' source the configuration describes, as open_chamber is for the chamber:
// the daemon opens it here and talks to a ThermistorSource, never naming the module's class.
// One kind so far (the Modbus input module): a second would add a `kind` to the configuration
// and a table as chamber_registry.hpp's (docs/adding-a-device.md, "Other devices"). No I/O (the
// first read connects).
std::unique_ptr<ThermistorSource> open_thermistor_source(const ThermistorModuleConfig& config,
                                                         const std::vector<UnitConfig>& units);

}  // namespace fogbench::drivers
