// Coil thermistor input module: request planning, reading, per-sensor conversion and errors.
#include "fogbench/drivers/thermistor_module.hpp"

#include <algorithm>

namespace fogbench::drivers {

namespace {
constexpr std::uint16_t max_block_registers = 125;  // Modbus limit for one read request
}

ThermistorModule::ThermistorModule(ThermistorModuleConfig config, std::vector<UnitConfig> units,
                                   ModbusLink::Clock clock)
    : config_(std::move(config)),
      units_(std::move(units)),
      link_(config_.modbus, "thermistor module", std::move(clock)) {
  for (std::size_t u = 0; u < units_.size(); ++u) {
    for (std::size_t k = 0; k <= units_[u].axis_thermistors.size(); ++k) {
      sensors_.push_back({u, 1, k, 0, 0});
      sensors_.push_back({u, 2, k, 0, 0});
    }
  }
  auto reg = [&](const Sensor& s) -> const RegisterSpec& { return channel(s).reg; };
  // Sort by table and address and merge touching registers: reading 16 sensors costs one round
  // trip instead of 16. Only touching ones, since a gap may hold addresses the module refuses.
  std::vector<std::size_t> order(sensors_.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    const auto& ra = reg(sensors_[a]);
    const auto& rb = reg(sensors_[b]);
    return std::pair(ra.function, ra.address) < std::pair(rb.function, rb.address);
  });
  for (std::size_t i : order) {
    Sensor& s = sensors_[i];
    const RegisterSpec& r = reg(s);
    const bool extend = !blocks_.empty() && blocks_.back().function == r.function &&
                        blocks_.back().address + blocks_.back().count == r.address &&
                        blocks_.back().count + r.width() <= max_block_registers;
    if (!extend) blocks_.push_back({r.function, r.address, 0});
    s.block = blocks_.size() - 1;
    s.offset = blocks_.back().count;
    blocks_.back().count = static_cast<std::uint16_t>(blocks_.back().count + r.width());
  }
}

const ThermistorChannelConfig& ThermistorModule::channel(const Sensor& s) const {
  const UnitConfig& u = units_[s.unit];
  if (s.axis == 0) return s.which == 1 ? u.t1 : u.t2;
  return u.axis_thermistors[s.axis - 1][s.which == 1 ? 0 : 1];
}

Result<std::vector<CoilTemperatures>> ThermistorModule::read_all() {
  std::vector<std::vector<std::uint16_t>> words(blocks_.size());
  std::vector<std::optional<DriverError>> block_error(blocks_.size());
  for (std::size_t b = 0; b < blocks_.size(); ++b) {
    words[b].resize(blocks_[b].count);
    auto ok = link_.read(blocks_[b].function, blocks_[b].address, words[b]);
    if (!ok) {
      const auto code = ok.error().code;
      if (code == ErrorCode::timeout || code == ErrorCode::connection) {
        return std::unexpected(ok.error());
      }
      block_error[b] = ok.error();
    }
  }
  std::vector<CoilTemperatures> out;
  out.reserve(units_.size());
  for (const auto& u : units_) {
    out.push_back({u.serial, fail(ErrorCode::io, "not read"), fail(ErrorCode::io, "not read")});
    out.back().axis_t1_c.assign(u.axis_thermistors.size(), fail(ErrorCode::io, "not read"));
    out.back().axis_t2_c.assign(u.axis_thermistors.size(), fail(ErrorCode::io, "not read"));
  }
  for (const Sensor& s : sensors_) {
    const UnitConfig& unit = units_[s.unit];
    const ThermistorChannelConfig& ch = channel(s);
    // Per axis the sensor's name says whose coil: "T1y"; a unit's shared pair is "T1", "T2".
    const std::string who = "unit " + unit.serial + (s.which == 1 ? " T1" : " T2") +
                            (unit.has_axis_thermistors() ? std::string(1, "xyz"[s.axis]) : std::string());
    Result<double> value = [&]() -> Result<double> {
      if (block_error[s.block]) {
        return fail(block_error[s.block]->code, who + ": " + block_error[s.block]->message);
      }
      return convert_thermistor(
          ch, std::span<const std::uint16_t>(words[s.block].data() + s.offset, ch.reg.width()), who);
    }();
    CoilTemperatures& to = out[s.unit];
    if (s.axis == 0) (s.which == 1 ? to.t1_c : to.t2_c) = std::move(value);
    else (s.which == 1 ? to.axis_t1_c : to.axis_t2_c)[s.axis - 1] = std::move(value);
  }
  return out;
}

std::unique_ptr<ThermistorSource> open_thermistor_source(const ThermistorModuleConfig& config,
                                                         const std::vector<UnitConfig>& units) {
  return std::make_unique<ThermistorModule>(config, units);
}

}  // namespace fogbench::drivers
