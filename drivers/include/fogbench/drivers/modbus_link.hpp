// A blocking Modbus client connection (TCP or RTU) with a response timeout, reconnection under
// exponential backoff, and every failure returned as a value. The chamber and the thermistor
// module each own one. libmodbus blocks: run these calls on a worker thread, never an event loop.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>

#include "fogbench/drivers/backoff.hpp"
#include "fogbench/drivers/config.hpp"
#include "fogbench/drivers/error.hpp"
#include "fogbench/drivers/register_map.hpp"

namespace fogbench::drivers {

class ModbusLink {
 public:
  using Clock = std::function<std::chrono::steady_clock::time_point()>;

  // No I/O here: the first request connects. `name` prefixes messages ("chamber").
  // An empty clock means std::chrono::steady_clock::now.
  ModbusLink(ModbusEndpoint endpoint, std::string name, Clock clock = {});
  ~ModbusLink();
  ModbusLink(ModbusLink&&) noexcept;
  ModbusLink& operator=(ModbusLink&&) noexcept;
  ModbusLink(const ModbusLink&) = delete;
  ModbusLink& operator=(const ModbusLink&) = delete;

  // Connects if not connected. While a backoff delay runs it returns `connection` at once,
  // without touching the network, saying when the next attempt is due.
  Result<void> connect();
  void disconnect() noexcept;
  bool is_connected() const noexcept;

  // Reads `out.size()` registers or bits from a table (bits arrive as 0/1 words). Fails with
  // timeout or connection (the link is then closed and the backoff advanced), protocol (an
  // exception reply: the link stays up) or corrupt (bad CRC on RTU).
  Result<void> read(RegisterFunction function, std::uint16_t address, std::span<std::uint16_t> out);
  Result<void> write_registers(std::uint16_t address, std::span<const std::uint16_t> words);
  Result<void> write_coil(std::uint16_t address, bool on);

  // Typed access through a register description (scale, offset, type, word order).
  Result<double> read_value(const RegisterSpec& spec);
  Result<std::uint32_t> read_raw(const RegisterSpec& spec);
  Result<void> write_value(const RegisterSpec& spec, double value);

  const ModbusEndpoint& endpoint() const noexcept;
  const Backoff& backoff() const noexcept;
  const std::string& name() const noexcept;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace fogbench::drivers
