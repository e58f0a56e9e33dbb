// Configuration of the drivers (chamber, thermistor module, gyro bus, units under test) and its
// parsing from JSON; every refusal names the field ("units[1].gyro.node_id: expected an integer
// 1..2047"). The JSON shape is documented with examples in docs/drivers.md.
#pragma once

#include <nlohmann/json_fwd.hpp>

#include <cstdint>
#include <filesystem>
#include <optional>
#include <array>
#include <string>
#include <string_view>
#include <vector>

#include "fogbench/drivers/backoff.hpp"
#include "fogbench/drivers/error.hpp"
#include "fogbench/drivers/register_map.hpp"
#include "fogbench/drivers/sample_accumulator.hpp"
#include "fogbench/drivers/serial_frame.hpp"
#include "fogbench/drivers/thermistor_conversion.hpp"

namespace fogbench::drivers {

// Where a Modbus device is and how patiently to talk to it.
struct ModbusEndpoint {
  enum class Transport { tcp, rtu };
  Transport transport = Transport::tcp;
  std::string host = "127.0.0.1";  // tcp: name or address
  std::uint16_t port = 502;        // tcp
  std::string device;              // rtu: serial device, e.g. /dev/ttyUSB0
  int baud = 19200;                // rtu
  char parity = 'N';               // rtu: 'N', 'E' or 'O'
  int data_bits = 8;               // rtu
  int stop_bits = 1;               // rtu
  int unit_id = 1;                 // Modbus unit (slave) id, 1..247
  int response_timeout_ms = 1000;  // per request; also bounds a TCP connect
  BackoffConfig backoff;           // between reconnection attempts

  // "tcp 127.0.0.1:1502 unit 1" or "rtu /dev/ttyUSB0 19200 8N1 unit 1", for messages.
  std::string describe() const;
};

// Where a line-oriented (ASCII) controller is: TCP, or a serial port (termios).
struct LineEndpoint {
  enum class Transport { tcp, serial };
  Transport transport = Transport::tcp;
  std::string host = "127.0.0.1";  // tcp
  std::uint16_t port = 0;          // tcp; 0 until parsed (each kind has its default)
  std::string device;              // serial, e.g. /dev/ttyUSB0
  int baud = 9600;                 // serial
  char parity = 'N';               // serial: 'N', 'E' or 'O'
  int data_bits = 8;               // serial
  int stop_bits = 1;               // serial
  int response_timeout_ms = 1000;  // per command; also bounds a TCP connect
  BackoffConfig backoff;           // between reconnection attempts

  // "tcp 127.0.0.1:57732" or "serial /dev/ttyUSB0 9600 8N1", for messages.
  std::string describe() const;
};

struct LimitsC {
  double min_c = 0;
  double max_c = 0;
};

// The chamber: `kind` names its driver in the registry (chamber_registry.hpp); the fields each
// kind reads are documented in docs/drivers.md. A configuration without "kind" is "modbus".
struct ChamberConfig {
  std::string kind = "modbus";
  ModbusEndpoint modbus;                 // modbus
  LineEndpoint line;                     // espec, simserv
  int simserv_chamber_index = 1;         // simserv: the chamber's index on its server (1..)
  RegisterMap map;
  std::string map_file;                  // where the map came from ("" when inline)
  LimitsC pv_limits_c{-90.0, 200.0};     // a process value outside is implausible (bring-up)
  LimitsC setpoint_limits_c{-70.0, 180.0};  // setpoints outside are refused before writing
};

struct ThermistorModuleConfig {
  ModbusEndpoint modbus;
};

// One bench slot (a fixture position): its gyro on the CAN bus and its coil thermistors on the
// input module. The serial of the unit in it is given when a run starts (run.start's `slots`);
// `serial` here is only a default, empty when none is configured.
struct UnitConfig {
  std::string slot;    // the position's name: "A", "B", ... by index unless configured
  std::string serial;  // the default serial, or 
  GyroChannelConfig gyro;
  ThermistorChannelConfig t1;  // coil centre (a three-axis unit with thermistors per axis: x's)
  ThermistorChannelConfig t2;  // coil outer wall (idem)
  // A three-axis unit whose axes have their own coil thermistors (configuration
  // "thermistors": {"x": {"t1", "t2"}, "y": {...}, "z": {...}}): y's and z's centre and outer
  // wall, [0] y and [1] z, each {t1, t2}; t1 and t2 above are x's. Empty when the axes share t1
  // and t2 (configuration "thermistors": {"t1", "t2"}).
  std::vector<std::array<ThermistorChannelConfig, 2>> axis_thermistors;
  bool has_axis_thermistors() const noexcept { return !axis_thermistors.empty(); }
};

// A unit's gyro on a serial line of its own (a unit's "gyro_line"), beside the bus the others
// share (docs/drivers.md "Several serial gyros, and serial with CAN").
struct SerialGyroLine {
  std::uint16_t node_id = 0;  // the unit it carries: its samples, as on the bus
  std::string transport;      // "serial:/dev/ttyUSB1?baud=921600&framing=8N1"
  serial::FrameFormat frame;
  std::string frame_file = {};  // where the frame came from ("" when inline)
  std::string key = {};         // "units[1].gyro_line", for messages
};

struct GyroBusConfig {
  // "can:can0", "unix:/run/fogbench/can.sock", "replay:file.log[?speed=N]",
  // "serial:/dev/ttyUSB0?baud=921600"; empty when every unit has a line of its own
  std::string transport;
  // serial only (required there, refused elsewhere): the gyro's binary frame layout, inline or
  // from a file named relative to the configuration's directory (docs/drivers.md "Serial gyros").
  std::optional<serial::FrameFormat> frame = std::nullopt;
  std::string frame_file = {};  // where the frame came from ("" when inline)
  // The units read on serial lines of their own (units[i].gyro_line), in the units' order; the
  // other units are read on `transport`.
  std::vector<SerialGyroLine> lines = {};
};

struct DriversConfig {
  ChamberConfig chamber;
  ThermistorModuleConfig thermistors;
  GyroBusConfig gyro_bus;
  std::vector<UnitConfig> units;
};

Result<ModbusEndpoint> parse_modbus_endpoint(const nlohmann::json& value, const std::string& path);
Result<GyroChannelConfig> parse_gyro_channel(const nlohmann::json& value, const std::string& path);
// `index` is the unit's place in `units`: it names the slot when "slot" is absent.
Result<UnitConfig> parse_unit_config(const nlohmann::json& value, const std::string& path,
                                     std::size_t index = 0);

// A slot's name: 1..kMaxSlotBytes characters out of A-Z a-z 0-9 _ - (a fixture label, typed
// at the command line and on the panel). "" when good, else why not.
inline constexpr std::size_t kMaxSlotBytes = 16;
std::string check_slot_name(std::string_view name);
// The slot name of the unit at `index` when none is configured: A..Z, then AA, AB, ...
std::string default_slot_name(std::size_t index);

// A line-oriented controller's endpoint ({"transport": "tcp", "host", "port"} or
// {"transport": "serial", "device", "baud", ...}); `default_port` when "port" is absent.
Result<LineEndpoint> parse_line_endpoint(const nlohmann::json& value, const std::string& path,
                                         std::uint16_t default_port, bool serial_allowed);

// The Modbus chamber's own fields ("modbus", "map") into `out`: the registry's parser for kind
// "modbus".
Result<void> parse_modbus_chamber_fields(const nlohmann::json& value, const std::string& path,
                                         const std::filesystem::path& map_dir, ChamberConfig& out);

// "kind" (default "modbus") picks the chamber's driver in the registry, which reads its fields;
// "map" (kind modbus) is an inline map object or a file name, resolved against `map_dir` when relative.
Result<ChamberConfig> parse_chamber_config(const nlohmann::json& value, const std::string& path,
                                           const std::filesystem::path& map_dir);

// The whole {"chamber", "thermistors", "gyro_bus", "units"} object, with the checks that span
// units: distinct slot names, default serials and node ids, no two thermistor channels on one register.
Result<DriversConfig> parse_drivers_config(const nlohmann::json& value,
                                           const std::filesystem::path& map_dir,
                                           const std::string& path = "");

}  // namespace fogbench::drivers
