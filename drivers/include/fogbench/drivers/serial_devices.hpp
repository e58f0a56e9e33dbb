// The serial devices a bench's configuration opens, for the service's device policy: the
// systemd unit may open only the devices it allows (DeviceAllow=), and ships allowing
// /dev/ttyUSB* alone (issue 28). fogbenchd --check-config names the others; --device-allow
// prints the unit's drop-in for all of them (docs/daemon.md, "Serial devices").
#pragma once

#include <string>
#include <vector>

#include "fogbench/drivers/config.hpp"

namespace fogbench::drivers {

struct SerialDevice {
  std::string path;  // as configured, e.g. /dev/ttyACM0, /dev/serial/by-id/usb-...
  std::string key;   // the configuration key that names it, e.g. drivers.chamber.line.device
};

// In the order chamber, thermistor module, serial gyro (gyro_bus.transport serial:DEVICE), the
// units' own lines (units[i].gyro_line.transport); a device named twice is listed once (its first key).
std::vector<SerialDevice> serial_devices(const DriversConfig& c, const std::string& path = "drivers");

// Whether the shipped unit's `DeviceAllow=char-ttyUSB rw` covers a device path: /dev/ttyUSB<N>
// only (a symlink such as /dev/serial/by-id/... is judged by its name: systemd resolves it at
// start, so it is named in the drop-in all the same).
bool allowed_by_shipped_unit(const std::string& device_path);

// The drop-in that allows every device (`systemctl edit fogbenchd` takes its [Service] lines).
std::string device_allow_dropin(const std::vector<SerialDevice>& devices, const std::string& config_path);

}  // namespace fogbench::drivers
