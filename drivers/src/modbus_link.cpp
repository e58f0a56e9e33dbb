// libmodbus behind a value-returning API: connection management, backoff, error classification.
#include "fogbench/drivers/modbus_link.hpp"

#include <modbus/modbus.h>

#include <cassert>
#include <cerrno>
#include <vector>

namespace fogbench::drivers {

struct ModbusLink::Impl {
  ModbusEndpoint endpoint;
  std::string name;
  Clock clock;
  Backoff backoff;
  modbus_t* ctx = nullptr;

  ~Impl() { close(); }

  void close() noexcept {
    if (ctx != nullptr) {
      modbus_close(ctx);
      modbus_free(ctx);
      ctx = nullptr;
    }
  }

  std::string prefix() const { return name + " (" + endpoint.describe() + ")"; }

  // A failed request: classify errno, and for link-level failures drop the connection so the
  // next request starts from a known state (a late reply cannot be taken for the next answer).
  std::unexpected<DriverError> request_failed(const std::string& what, int err) {
    ErrorCode code = ErrorCode::connection;
    bool link_down = true;
    if (err == ETIMEDOUT) {
      code = ErrorCode::timeout;
    } else if (err == EMBBADCRC) {
      code = ErrorCode::corrupt;
    } else if (err >= EMBXILFUN && err <= EMBXGTAR) {
      code = ErrorCode::protocol;  // the device answered with an exception: the link is fine
      link_down = false;
    } else if (err > MODBUS_ENOBASE) {
      code = ErrorCode::protocol;  // malformed or mismatched reply: resynchronise by reconnecting
    }
    const std::string message = prefix() + ": " + what + ": " + modbus_strerror(err);
    if (link_down) {
      close();
      backoff.record_failure(clock());
    } else if (endpoint.transport == ModbusEndpoint::Transport::rtu) {
      modbus_flush(ctx);
    }
    return fail(code, message);
  }

  Result<void> connect() {
    if (ctx != nullptr) return {};
    const auto now = clock();
    if (!backoff.may_attempt(now)) {
      return fail(ErrorCode::connection,
                  prefix() + ": not connected; next attempt in " +
                      std::to_string(backoff.remaining(now).count()) + " ms (after " +
                      std::to_string(backoff.consecutive_failures()) + " failures)");
    }
    if (endpoint.transport == ModbusEndpoint::Transport::tcp) {
      // The _pi variant resolves host names and IPv6; plain modbus_new_tcp takes IPv4 only.
      ctx = modbus_new_tcp_pi(endpoint.host.c_str(), std::to_string(endpoint.port).c_str());
    } else {
      ctx = modbus_new_rtu(endpoint.device.c_str(), endpoint.baud, endpoint.parity,
                           endpoint.data_bits, endpoint.stop_bits);
    }
    if (ctx == nullptr) {
      const int err = errno;
      backoff.record_failure(now);
      return fail(ErrorCode::config, prefix() + ": cannot create a libmodbus context: " +
                                         modbus_strerror(err));
    }
    modbus_set_slave(ctx, endpoint.unit_id);
    const auto ms = static_cast<std::uint32_t>(endpoint.response_timeout_ms);
    modbus_set_response_timeout(ctx, ms / 1000, (ms % 1000) * 1000);
    // Recovery is ours (backoff, reconnect on the next call), not libmodbus's own retry loop.
    modbus_set_error_recovery(ctx, MODBUS_ERROR_RECOVERY_NONE);
    if (modbus_connect(ctx) == -1) {
      const int err = errno;
      modbus_free(ctx);
      ctx = nullptr;
      backoff.record_failure(clock());
      return fail(err == ETIMEDOUT ? ErrorCode::timeout : ErrorCode::connection,
                  prefix() + ": connect: " + modbus_strerror(err));
    }
    return {};
  }
};

ModbusLink::ModbusLink(ModbusEndpoint endpoint, std::string name, Clock clock)
    : impl_(std::make_unique<Impl>()) {
  impl_->endpoint = std::move(endpoint);
  impl_->name = std::move(name);
  impl_->clock = clock ? std::move(clock) : Clock([] { return std::chrono::steady_clock::now(); });
  impl_->backoff = Backoff(impl_->endpoint.backoff);
}

ModbusLink::~ModbusLink() = default;
ModbusLink::ModbusLink(ModbusLink&&) noexcept = default;
ModbusLink& ModbusLink::operator=(ModbusLink&&) noexcept = default;

Result<void> ModbusLink::connect() { return impl_->connect(); }
void ModbusLink::disconnect() noexcept { impl_->close(); }
bool ModbusLink::is_connected() const noexcept { return impl_->ctx != nullptr; }
const ModbusEndpoint& ModbusLink::endpoint() const noexcept { return impl_->endpoint; }
const Backoff& ModbusLink::backoff() const noexcept { return impl_->backoff; }
const std::string& ModbusLink::name() const noexcept { return impl_->name; }

Result<void> ModbusLink::read(RegisterFunction function, std::uint16_t address,
                              std::span<std::uint16_t> out) {
  assert(!out.empty());
  assert(is_bit_table(function) ? out.size() <= MODBUS_MAX_READ_BITS
                                : out.size() <= MODBUS_MAX_READ_REGISTERS);
  if (auto ok = impl_->connect(); !ok) return ok;
  const int n = static_cast<int>(out.size());
  int rc = -1;
  switch (function) {
    case RegisterFunction::holding: rc = modbus_read_registers(impl_->ctx, address, n, out.data()); break;
    case RegisterFunction::input: rc = modbus_read_input_registers(impl_->ctx, address, n, out.data()); break;
    case RegisterFunction::coil:
    case RegisterFunction::discrete: {
      std::vector<std::uint8_t> bits(out.size());
      rc = function == RegisterFunction::coil ? modbus_read_bits(impl_->ctx, address, n, bits.data())
                                              : modbus_read_input_bits(impl_->ctx, address, n, bits.data());
      for (std::size_t i = 0; i < bits.size(); ++i) out[i] = bits[i] ? 1 : 0;
      break;
    }
  }
  if (rc != n) {
    const int err = rc == -1 ? errno : EMBBADDATA;
    std::string what = "read " + std::string(to_string(function)) + " " + std::to_string(address);
    if (n > 1) what += ".." + std::to_string(address + n - 1);
    return impl_->request_failed(what, err);
  }
  impl_->backoff.record_success();
  return {};
}

Result<void> ModbusLink::write_registers(std::uint16_t address, std::span<const std::uint16_t> words) {
  assert(!words.empty() && words.size() <= MODBUS_MAX_WRITE_REGISTERS);
  if (auto ok = impl_->connect(); !ok) return ok;
  const int n = static_cast<int>(words.size());
  // One register goes as function 06, which every controller supports; two as 16, which writes
  // both halves of a 32-bit value in one request so the device never sees half a value.
  const int rc = n == 1 ? modbus_write_register(impl_->ctx, address, words[0])
                        : modbus_write_registers(impl_->ctx, address, n, words.data());
  if (rc != n) {
    const int err = rc == -1 ? errno : EMBBADDATA;
    std::string what = "write holding " + std::to_string(address);
    if (n > 1) what += ".." + std::to_string(address + n - 1);
    return impl_->request_failed(what, err);
  }
  impl_->backoff.record_success();
  return {};
}

Result<void> ModbusLink::write_coil(std::uint16_t address, bool on) {
  if (auto ok = impl_->connect(); !ok) return ok;
  if (modbus_write_bit(impl_->ctx, address, on ? 1 : 0) != 1) {
    const int err = errno;
    return impl_->request_failed("write coil " + std::to_string(address), err);
  }
  impl_->backoff.record_success();
  return {};
}

Result<std::uint32_t> ModbusLink::read_raw(const RegisterSpec& spec) {
  std::uint16_t words[2] = {0, 0};
  if (auto ok = read(spec.function, spec.address, std::span(words, spec.width())); !ok) {
    return std::unexpected(ok.error());
  }
  return raw_unsigned(spec, std::span<const std::uint16_t>(words, spec.width()));
}

Result<double> ModbusLink::read_value(const RegisterSpec& spec) {
  std::uint16_t words[2] = {0, 0};
  if (auto ok = read(spec.function, spec.address, std::span(words, spec.width())); !ok) {
    return std::unexpected(ok.error());
  }
  auto value = decode_value(spec, std::span<const std::uint16_t>(words, spec.width()));
  if (!value) return fail(value.error().code, impl_->prefix() + ": " + value.error().message);
  return value;
}

Result<void> ModbusLink::write_value(const RegisterSpec& spec, double value) {
  if (spec.function == RegisterFunction::coil) return write_coil(spec.address, value != 0.0);
  assert(spec.function == RegisterFunction::holding);
  auto words = encode_value(spec, value);
  if (!words) return fail(words.error().code, impl_->prefix() + ": " + words.error().message);
  return write_registers(spec.address, std::span<const std::uint16_t>(words->data(), spec.width()));
}

}  // namespace fogbench::drivers
