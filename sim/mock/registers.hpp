// The Modbus data the mock bench serves: one libmodbus mapping per device, covering exactly the
// registers its map (chamber) or channels (thermistor module) name, so a request elsewhere gets
// an illegal-address exception as from a real device; and the translation between the
// simulation's values and those registers, through the drivers' register definitions.
// Not thread-safe: the bench guards both devices with one mutex.
#pragma once

#include <modbus/modbus.h>

#include <array>
#include <cstdint>
#include <expected>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "fogbench/drivers/register_map.hpp"
#include "layout.hpp"

namespace fogbench::mock {

class DeviceMapping {
 public:
  // A mapping spanning, in each table, the lowest to the highest register the specs use.
  static std::expected<DeviceMapping, std::string> create(std::span<const drivers::RegisterSpec> specs);

  modbus_mapping_t* get() const noexcept { return mapping_.get(); }
  void write(const drivers::RegisterSpec& spec, std::array<std::uint16_t, 2> words) noexcept;
  std::array<std::uint16_t, 2> read(const drivers::RegisterSpec& spec) const noexcept;

 private:
  struct Free {
    void operator()(modbus_mapping_t* m) const noexcept { modbus_mapping_free(m); }
  };
  std::unique_ptr<modbus_mapping_t, Free> mapping_;
};

// What the chamber's registers show besides its process value.
struct ChamberShown {
  double process_value_c = 0;
  bool freeze_pv = false;  // leave the process value as it is
  bool heating = false, cooling = false, at_setpoint = false;
  bool alarm = false;
};

class ChamberRegisters {
 public:
  // Sets identity and units to the map's expected values, the setpoint, and run on or off.
  static std::expected<ChamberRegisters, std::string> create(const drivers::RegisterMap& map,
                                                             double setpoint_c, bool running);

  modbus_mapping_t* mapping() const noexcept { return regs_.get(); }
  // The setpoint as last written by a client; `fallback` when the registers hold no finite
  // number (a client wrote NaN).
  double setpoint_c(double fallback) const;
  bool running() const;
  // What the ASCII controllers answer from (ascii_chamber.hpp): the process value as shown, the
  // alarm as shown, and a setpoint or run state written as a Modbus client would write them.
  double process_value_c() const;
  bool alarm() const;
  void write_setpoint_c(double temp_c);
  void write_running(bool run);
  // Whether a write request (function 6 or 16, `count` registers from `address`) touches the
  // setpoint: the refuse_setpoint fault answers it with an exception.
  bool writes_setpoint(int function, int address, int count) const;
  void show(const ChamberShown& shown);
  // Raises or clears the alarm alone (a fault switched between two steps).
  void show_alarm(bool alarm);

 private:
  drivers::RegisterMap map_;
  DeviceMapping regs_;
};

class ThermistorRegisters {
 public:
  static std::expected<ThermistorRegisters, std::string> create(const std::vector<UnitLayout>& units);

  modbus_mapping_t* mapping() const noexcept { return regs_.get(); }
  // One sensor (1 = T1, 2 = T2) of one unit's axis (0: the unit's, x's with thermistors per
  // axis; 1 y, 2 z: UnitLayout::axis_thermistors): its temperature, or an open circuit.
  void show(std::size_t unit, int sensor, double temp_c, bool open, std::size_t axis = 0);

 private:
  std::vector<UnitLayout> units_;
  DeviceMapping regs_;
};

}  // namespace fogbench::mock
