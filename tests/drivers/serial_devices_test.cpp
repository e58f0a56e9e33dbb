// The serial devices a configuration opens, for the service's DeviceAllow= (issue 28).
#include <catch2/catch.hpp>

#include "fogbench/drivers/serial_devices.hpp"

using namespace fogbench::drivers;

TEST_CASE("serial devices: the RTU and serial endpoints a configuration opens, each once, with its key", "[drivers][devices]") {
  DriversConfig c;
  CHECK(serial_devices(c).empty());  // TCP everywhere (the defaults)
  c.chamber.modbus.transport = ModbusEndpoint::Transport::rtu;
  c.chamber.modbus.device = "/dev/ttyACM0";
  c.thermistors.modbus.transport = ModbusEndpoint::Transport::rtu;
  c.thermistors.modbus.device = "/dev/ttyACM0";  // one RS-485 line for both: listed once
  auto d = serial_devices(c);
  REQUIRE(d.size() == 1);
  CHECK(d[0].path == "/dev/ttyACM0");
  CHECK(d[0].key == "drivers.chamber.modbus.device");
  c.thermistors.modbus.device = "/dev/ttyUSB1";
  d = serial_devices(c);
  REQUIRE(d.size() == 2);
  CHECK(d[1].key == "drivers.thermistors.modbus.device");
  // An ASCII chamber on a serial line: its line's device, not the unused Modbus endpoint's.
  c.chamber.kind = "espec";
  c.chamber.line.transport = LineEndpoint::Transport::serial;
  c.chamber.line.device = "/dev/ttyS1";
  d = serial_devices(c);
  REQUIRE(d.size() == 2);
  CHECK(d[0].path == "/dev/ttyS1");
  CHECK(d[0].key == "drivers.chamber.line.device");
  c.chamber.line.transport = LineEndpoint::Transport::tcp;
  CHECK(serial_devices(c).size() == 1);
  // A serial gyro's line.
  c.gyro_bus.transport = "serial:/dev/ttyUSB3?baud=921600";
  d = serial_devices(c);
  REQUIRE(d.size() == 2);
  CHECK(d[1].path == "/dev/ttyUSB3");
  CHECK(d[1].key == "drivers.gyro_bus.transport");
  // Units on serial lines of their own, keyed as parsed (parse_drivers_config's path).
  c.gyro_bus.transport = "unix:/run/fogbench/can.sock";
  c.gyro_bus.lines.push_back({257, "serial:/dev/ttyUSB4?baud=921600", {}, "", "drivers.units[0].gyro_line"});
  c.gyro_bus.lines.push_back({258, "serial:/dev/ttyUSB5", {}, "", "drivers.units[1].gyro_line"});
  d = serial_devices(c);
  REQUIRE(d.size() == 3);
  CHECK(d[1].path == "/dev/ttyUSB4");
  CHECK(d[1].key == "drivers.units[0].gyro_line.transport");
  CHECK(d[2].path == "/dev/ttyUSB5");
  CHECK(d[2].key == "drivers.units[1].gyro_line.transport");
}

TEST_CASE("serial devices: what the shipped unit's DeviceAllow=char-ttyUSB covers, and the drop-in for the rest", "[drivers][devices]") {
  CHECK(allowed_by_shipped_unit("/dev/ttyUSB0"));
  CHECK(allowed_by_shipped_unit("/dev/ttyUSB12"));
  CHECK_FALSE(allowed_by_shipped_unit("/dev/ttyUSB"));
  CHECK_FALSE(allowed_by_shipped_unit("/dev/ttyACM0"));
  CHECK_FALSE(allowed_by_shipped_unit("/dev/ttyS0"));
  CHECK_FALSE(allowed_by_shipped_unit("/dev/serial/by-id/usb-FTDI_FT232R-if00-port0"));
  CHECK_FALSE(allowed_by_shipped_unit("/dev/ttyUSB0x"));
  const auto text = device_allow_dropin({{"/dev/ttyACM0", "drivers.chamber.modbus.device"},
                                         {"/dev/serial/by-id/usb-x", "drivers.thermistors.modbus.device"}},
                                        "/etc/fogbench/fogbenchd.json");
  CHECK_THAT(text, Catch::Contains("/etc/fogbench/fogbenchd.json"));
  CHECK_THAT(text, Catch::EndsWith("[Service]\nDeviceAllow=/dev/ttyACM0 rw\nDeviceAllow=/dev/serial/by-id/usb-x rw\n"));
}
