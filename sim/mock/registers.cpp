// Served registers; see registers.hpp.
#include "registers.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>

namespace fogbench::mock {

using drivers::RegisterFunction;
using drivers::RegisterSpec;

namespace {

std::uint16_t* words_of(modbus_mapping_t& m, const RegisterSpec& spec) {
  switch (spec.function) {
    case RegisterFunction::holding: return m.tab_registers + (spec.address - m.start_registers);
    case RegisterFunction::input: return m.tab_input_registers + (spec.address - m.start_input_registers);
    default: return nullptr;
  }
}

std::uint8_t* bits_of(modbus_mapping_t& m, const RegisterSpec& spec) {
  switch (spec.function) {
    case RegisterFunction::coil: return m.tab_bits + (spec.address - m.start_bits);
    case RegisterFunction::discrete: return m.tab_input_bits + (spec.address - m.start_input_bits);
    default: return nullptr;
  }
}

}  // namespace

std::expected<DeviceMapping, std::string> DeviceMapping::create(std::span<const RegisterSpec> specs) {
  // Per table: first address and one past the last register used (first > end: unused).
  std::array<int, 4> first, end;
  first.fill(std::numeric_limits<int>::max());
  end.fill(0);
  for (const auto& s : specs) {
    const auto t = static_cast<std::size_t>(s.function);
    first[t] = std::min<int>(first[t], s.address);
    end[t] = std::max<int>(end[t], s.address + s.width());
  }
  auto start = [&](RegisterFunction f) {
    const auto t = static_cast<std::size_t>(f);
    return first[t] < end[t] ? first[t] : 0;
  };
  auto count = [&](RegisterFunction f) {
    const auto t = static_cast<std::size_t>(f);
    return first[t] < end[t] ? end[t] - first[t] : 0;
  };
  DeviceMapping d;
  d.mapping_.reset(modbus_mapping_new_start_address(
      static_cast<unsigned>(start(RegisterFunction::coil)), static_cast<unsigned>(count(RegisterFunction::coil)),
      static_cast<unsigned>(start(RegisterFunction::discrete)), static_cast<unsigned>(count(RegisterFunction::discrete)),
      static_cast<unsigned>(start(RegisterFunction::holding)), static_cast<unsigned>(count(RegisterFunction::holding)),
      static_cast<unsigned>(start(RegisterFunction::input)), static_cast<unsigned>(count(RegisterFunction::input))));
  if (!d.mapping_) return std::unexpected(std::string("cannot allocate a Modbus mapping: ") + modbus_strerror(errno));
  return d;
}

void DeviceMapping::write(const RegisterSpec& spec, std::array<std::uint16_t, 2> words) noexcept {
  if (drivers::is_bit_table(spec.function)) {
    *bits_of(*mapping_, spec) = words[0] != 0 ? 1 : 0;
    return;
  }
  std::copy_n(words.begin(), spec.width(), words_of(*mapping_, spec));
}

std::array<std::uint16_t, 2> DeviceMapping::read(const RegisterSpec& spec) const noexcept {
  if (drivers::is_bit_table(spec.function)) return {static_cast<std::uint16_t>(*bits_of(*mapping_, spec) ? 1 : 0), 0};
  std::array<std::uint16_t, 2> w{};
  std::copy_n(words_of(*mapping_, spec), spec.width(), w.begin());
  return w;
}

// ---- chamber -------------------------------------------------------------------------------

std::expected<ChamberRegisters, std::string> ChamberRegisters::create(const drivers::RegisterMap& map,
                                                                      double setpoint_c, bool running) {
  std::vector<RegisterSpec> specs = {map.setpoint, map.process_value, map.run.reg, map.alarm.reg};
  if (map.status) specs.push_back(map.status->reg);
  if (map.identity) specs.push_back(map.identity->reg);
  if (map.units) specs.push_back(map.units->reg);
  auto regs = DeviceMapping::create(specs);
  if (!regs) return std::unexpected(regs.error());
  ChamberRegisters c;
  c.map_ = map;
  c.regs_ = std::move(*regs);
  for (const auto* checked : {&map.identity, &map.units}) {
    if (*checked && (*checked)->expect) c.regs_.write((*checked)->reg, raw_words((*checked)->reg, *(*checked)->expect));
  }
  auto sp = drivers::encode_value(map.setpoint, setpoint_c);
  if (!sp) return std::unexpected("setpoint " + std::to_string(setpoint_c) + " degC: " + sp.error().message);
  c.regs_.write(map.setpoint, *sp);
  if (map.run.reg.function == RegisterFunction::coil) {
    c.regs_.write(map.run.reg, {static_cast<std::uint16_t>(running ? 1 : 0), 0});
  } else {
    c.regs_.write(map.run.reg, raw_words(map.run.reg, running ? map.run.on_value : map.run.off_value));
  }
  c.show({.process_value_c = setpoint_c, .at_setpoint = running});
  return c;
}

double ChamberRegisters::setpoint_c(double fallback) const {
  const auto w = regs_.read(map_.setpoint);
  auto v = drivers::decode_value(map_.setpoint, std::span<const std::uint16_t>(w.data(), map_.setpoint.width()));
  return v && std::isfinite(*v) ? *v : fallback;
}

bool ChamberRegisters::running() const {
  const auto w = regs_.read(map_.run.reg);
  if (map_.run.reg.function == RegisterFunction::coil) return w[0] != 0;
  return drivers::raw_unsigned(map_.run.reg, std::span<const std::uint16_t>(w.data(), map_.run.reg.width())) ==
         map_.run.on_value;
}

double ChamberRegisters::process_value_c() const {
  const auto w = regs_.read(map_.process_value);
  auto v = drivers::decode_value(map_.process_value,
                                 std::span<const std::uint16_t>(w.data(), map_.process_value.width()));
  return v ? *v : std::numeric_limits<double>::quiet_NaN();
}

bool ChamberRegisters::alarm() const {
  const auto& reg = map_.alarm.reg;
  const auto w = regs_.read(reg);
  if (drivers::is_bit_table(reg.function)) return w[0] != 0;
  return (drivers::raw_unsigned(reg, std::span<const std::uint16_t>(w.data(), reg.width())) & map_.alarm.mask) != 0;
}

void ChamberRegisters::write_setpoint_c(double temp_c) {
  if (auto words = drivers::encode_value(map_.setpoint, temp_c)) regs_.write(map_.setpoint, *words);
}

void ChamberRegisters::write_running(bool run) {
  if (map_.run.reg.function == RegisterFunction::coil) {
    regs_.write(map_.run.reg, {static_cast<std::uint16_t>(run ? 1 : 0), 0});
  } else {
    regs_.write(map_.run.reg, raw_words(map_.run.reg, run ? map_.run.on_value : map_.run.off_value));
  }
}

bool ChamberRegisters::writes_setpoint(int function, int address, int count) const {
  if (map_.setpoint.function != RegisterFunction::holding || (function != 6 && function != 16)) return false;
  const int a = map_.setpoint.address;
  return address < a + static_cast<int>(map_.setpoint.width()) && a < address + count;
}

void ChamberRegisters::show(const ChamberShown& s) {
  if (!s.freeze_pv) {
    // A value the register cannot hold (an int16 map far off scale) is clamped: a real
    // controller shows its limit rather than garbage.
    auto words = drivers::encode_value(map_.process_value, s.process_value_c);
    if (!words) words = drivers::encode_value(map_.process_value, s.process_value_c > 0 ? 999.0 : -999.0);
    if (words) regs_.write(map_.process_value, *words);
  }
  if (map_.status) {
    std::uint32_t raw = 0;
    for (const auto& [name, bit] : map_.status->bits) {
      const bool on = (name == "heating" && s.heating) || (name == "cooling" && s.cooling) ||
                      (name == "at_setpoint" && s.at_setpoint);
      if (on) raw |= 1u << bit;
    }
    regs_.write(map_.status->reg, raw_words(map_.status->reg, raw));
  }
  show_alarm(s.alarm);
}

void ChamberRegisters::show_alarm(bool alarm) {
  const auto& reg = map_.alarm.reg;
  if (drivers::is_bit_table(reg.function)) {
    regs_.write(reg, {static_cast<std::uint16_t>(alarm ? 1 : 0), 0});
  } else {
    // The lowest bit of the mask: an alarm as the map defines it.
    const std::uint32_t bit = map_.alarm.mask & (~map_.alarm.mask + 1u);
    regs_.write(reg, raw_words(reg, alarm ? bit : 0u));
  }
}

// ---- thermistor module ---------------------------------------------------------------------

std::expected<ThermistorRegisters, std::string> ThermistorRegisters::create(const std::vector<UnitLayout>& units) {
  std::vector<RegisterSpec> specs;
  for (const auto& u : units) {
    specs.push_back(u.t1.reg);
    specs.push_back(u.t2.reg);
    for (const auto& a : u.axis_thermistors)
      for (const auto& ch : a) specs.push_back(ch.reg);
  }
  auto regs = DeviceMapping::create(specs);
  if (!regs) return std::unexpected(regs.error());
  ThermistorRegisters t;
  t.units_ = units;
  t.regs_ = std::move(*regs);
  return t;
}

void ThermistorRegisters::show(std::size_t unit, int sensor, double temp_c, bool open, std::size_t axis) {
  const UnitLayout& u = units_[unit];
  if (axis > u.axis_thermistors.size()) return;  // the unit has no such axis's channels
  const auto& ch = axis == 0 ? (sensor == 1 ? u.t1 : u.t2) : u.axis_thermistors[axis - 1][sensor == 1 ? 0 : 1];
  if (open) {
    regs_.write(ch.reg, encode_open_circuit(ch));
    return;
  }
  auto words = encode_thermistor(ch, temp_c);
  if (words) regs_.write(ch.reg, *words);
}

}  // namespace fogbench::mock
