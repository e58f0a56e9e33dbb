// The serial devices a configuration opens (serial_devices.hpp).
#include "fogbench/drivers/serial_devices.hpp"

#include <algorithm>
#include <cctype>

#include "fogbench/drivers/can_transport.hpp"

namespace fogbench::drivers {

std::vector<SerialDevice> serial_devices(const DriversConfig& c, const std::string& path) {
  std::vector<SerialDevice> out;
  const auto add_full = [&](const std::string& device, const std::string& full_key) {
    if (device.empty()) return;
    if (std::any_of(out.begin(), out.end(), [&](const SerialDevice& d) { return d.path == device; })) return;
    out.push_back({device, full_key});
  };
  const auto add = [&](const std::string& device, const std::string& key) { add_full(device, path + "." + key); };
  const auto& ch = c.chamber;
  if (ch.kind == "modbus" && ch.modbus.transport == ModbusEndpoint::Transport::rtu)
    add(ch.modbus.device, "chamber.modbus.device");
  if (ch.kind != "modbus" && ch.line.transport == LineEndpoint::Transport::serial)
    add(ch.line.device, "chamber.line.device");
  if (c.thermistors.modbus.transport == ModbusEndpoint::Transport::rtu)
    add(c.thermistors.modbus.device, "thermistors.modbus.device");
  if (auto spec = parse_transport_spec(c.gyro_bus.transport); spec && spec->kind == TransportSpec::Kind::serial)
    add(spec->target, "gyro_bus.transport");
  for (const auto& line : c.gyro_bus.lines) {
    if (auto spec = parse_transport_spec(line.transport); spec && spec->kind == TransportSpec::Kind::serial)
      add_full(spec->target, line.key + ".transport");  // the key as parsed: already under its path
  }
  return out;
}

bool allowed_by_shipped_unit(const std::string& device_path) {
  constexpr std::string_view prefix = "/dev/ttyUSB";
  if (device_path.size() <= prefix.size() || device_path.compare(0, prefix.size(), prefix) != 0) return false;
  return std::all_of(device_path.begin() + static_cast<std::ptrdiff_t>(prefix.size()), device_path.end(),
                     [](char ch) { return std::isdigit(static_cast<unsigned char>(ch)) != 0; });
}

std::string device_allow_dropin(const std::vector<SerialDevice>& devices, const std::string& config_path) {
  std::string s = "# The serial devices " + config_path +
                  " opens, for fogbenchd's unit: systemctl edit fogbenchd (or fogbenchd@NAME),\n"
                  "# or save as /etc/systemd/system/fogbenchd.service.d/devices.conf and systemctl daemon-reload.\n"
                  "[Service]\n";
  for (const auto& d : devices) s += "DeviceAllow=" + d.path + " rw\n";
  return s;
}

}  // namespace fogbench::drivers
