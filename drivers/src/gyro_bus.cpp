// Routing of CAN frames from any transport to the per-unit sample accumulators.
#include "fogbench/drivers/gyro_bus.hpp"

#include <algorithm>
#include <cassert>

namespace fogbench::drivers {

GyroBus::GyroBus(std::unique_ptr<CanTransport> transport, std::vector<GyroChannelConfig> units)
    : transport_(std::move(transport)), units_(std::move(units)) {
  assert(transport_);
  accumulator_of_id_.fill(-1);
  first_of_unit_.reserve(units_.size());
  for (auto& u : units_) {
    assert(u.axes == 1 || u.axes == 3);
    if (u.axes != 3) u.axes = 1;  // a release build without the check: never an unread axis or none
    first_of_unit_.push_back(accumulators_.size());
    for (std::uint8_t k = 0; k < u.axes; ++k) {
      const std::uint16_t id = u.axis_id(k);
      assert(id >= 1 && id <= CAN_SFF_MASK);
      assert(accumulator_of_id_[id] < 0);
      accumulator_of_id_[id] = static_cast<std::int16_t>(accumulators_.size());
      accumulators_.emplace_back(u, k);
    }
  }
}

namespace {

// The CAN ids of every axis of these units (the kernel filter of a SocketCAN transport).
std::vector<std::uint16_t> ids_of(const std::vector<GyroChannelConfig>& units) {
  std::vector<std::uint16_t> ids;
  for (const auto& u : units) {
    for (std::uint8_t k = 0; k < u.axes; ++k) ids.push_back(u.axis_id(k));
  }
  return ids;
}

// A serial gyro's frame layout carries one rate: a three-axis unit cannot be read there.
Result<void> one_axis_on_serial(const GyroChannelConfig& unit) {
  if (unit.axes == 1) return {};
  return fail(ErrorCode::config, "gyro_bus: node " + std::to_string(unit.node_id) + " has " +
                                     std::to_string(unit.axes) + " axes, but a serial gyro's frame carries one axis");
}

}  // namespace

namespace {

// The transport of a bench with serial lines of its own (config.lines): each line's transport
// for its unit, and the shared one (when there is one, and units left for it) for the others.
Result<std::unique_ptr<CanTransport>> open_lines(const GyroBusConfig& config,
                                                 const std::vector<GyroChannelConfig>& units,
                                                 MonotonicClock clock) {
  std::vector<TransportPart> parts;
  std::vector<std::uint16_t> shared_ids;
  for (const auto& u : units) {
    const bool own = std::any_of(config.lines.begin(), config.lines.end(),
                                 [&](const SerialGyroLine& l) { return l.node_id == u.node_id; });
    if (!own) {
      for (std::uint8_t k = 0; k < u.axes; ++k) shared_ids.push_back(u.axis_id(k));
    }
  }
  if (!shared_ids.empty()) {
    if (config.transport.empty()) {
      return fail(ErrorCode::config, "gyro_bus: node " + std::to_string(shared_ids.front()) +
                                         " has no serial line of its own and gyro_bus.transport is empty");
    }
    auto spec = parse_transport_spec(config.transport);
    if (!spec) return std::unexpected(spec.error());
    if (spec->kind == TransportSpec::Kind::serial) {
      return fail(ErrorCode::config, "gyro_bus: a serial: gyro_bus.transport carries one unit; beside units' gyro_line it must be a bus (can:, unix:, replay:)");
    }
    auto t = open_transport(*spec, shared_ids, std::move(clock));
    if (!t) return std::unexpected(t.error());
    parts.push_back({std::move(*t), {}});
  }
  for (const auto& line : config.lines) {
    const auto unit = std::find_if(units.begin(), units.end(), [&](const GyroChannelConfig& u) { return u.node_id == line.node_id; });
    if (unit == units.end()) {
      return fail(ErrorCode::config, line.key + ": node " + std::to_string(line.node_id) + " is no unit of the bus");
    }
    auto spec = parse_transport_spec(line.transport);
    if (!spec) return fail(ErrorCode::config, line.key + ": " + spec.error().message);
    if (spec->kind != TransportSpec::Kind::serial) {
      return fail(ErrorCode::config, line.key + ".transport: expected serial:DEVICE[?baud=N][&framing=8N1]");
    }
    if (auto ok = one_axis_on_serial(*unit); !ok) return std::unexpected(ok.error());
    auto t = open_serial_gyro(spec->target, spec->baud, spec->framing, line.frame, *unit);
    if (!t) return std::unexpected(t.error());
    parts.push_back({std::move(*t), {line.node_id}});
  }
  return combine_transports(std::move(parts));
}

}  // namespace

Result<GyroBus> GyroBus::open(const GyroBusConfig& config, std::vector<GyroChannelConfig> units,
                              MonotonicClock clock) {
  if (!config.lines.empty()) {
    auto transport = open_lines(config, units, std::move(clock));
    if (!transport) return std::unexpected(transport.error());
    return GyroBus(std::move(*transport), std::move(units));
  }
  auto spec = parse_transport_spec(config.transport);
  if (!spec) return std::unexpected(spec.error());
  const auto ids = ids_of(units);
  if (spec->kind == TransportSpec::Kind::serial) {
    if (!config.frame || units.size() != 1) {
      return fail(ErrorCode::config, "gyro_bus: a serial: transport needs a frame layout and exactly one unit");
    }
    if (auto ok = one_axis_on_serial(units[0]); !ok) return std::unexpected(ok.error());
    auto transport = open_serial_gyro(spec->target, spec->baud, spec->framing, *config.frame, units[0]);
    if (!transport) return std::unexpected(transport.error());
    return GyroBus(std::move(*transport), std::move(units));
  }
  auto transport = open_transport(*spec, ids, std::move(clock));
  if (!transport) return std::unexpected(transport.error());
  return GyroBus(std::move(*transport), std::move(units));
}

Result<void> GyroBus::reopen(const GyroBusConfig& config, MonotonicClock clock) {
  if (!config.lines.empty()) {
    auto transport = open_lines(config, units_, std::move(clock));
    if (!transport) return std::unexpected(transport.error());
    (*transport)->take_over(*transport_);
    transport_ = std::move(*transport);
    return {};
  }
  auto spec = parse_transport_spec(config.transport);
  if (!spec) return std::unexpected(spec.error());
  const auto ids = ids_of(units_);
  if (spec->kind == TransportSpec::Kind::serial) {
    if (!config.frame || units_.size() != 1) {
      return fail(ErrorCode::config, "gyro_bus: a serial: transport needs a frame layout and exactly one unit");
    }
    if (auto ok = one_axis_on_serial(units_[0]); !ok) return std::unexpected(ok.error());
    auto transport = open_serial_gyro(spec->target, spec->baud, spec->framing, *config.frame, units_[0]);
    if (!transport) return std::unexpected(transport.error());
    (*transport)->take_over(*transport_);
    transport_ = std::move(*transport);
    return {};
  }
  auto transport = open_transport(*spec, ids, std::move(clock));
  if (!transport) return std::unexpected(transport.error());
  transport_ = std::move(*transport);
  return {};
}

Result<std::size_t> GyroBus::read_frames(std::vector<::can_frame>& frames) {
  frames.clear();
  auto n = transport_->read(frames);
  if (!n) return n;
  for (const auto& f : frames) route(f);
  return n;
}

void GyroBus::route(const ::can_frame& frame) noexcept {
  // The user-space filter: the same for every transport, since only SocketCAN can filter in the
  // kernel and a replayed log or the mock bench delivers everything.
  if ((frame.can_id & (CAN_EFF_FLAG | CAN_RTR_FLAG | CAN_ERR_FLAG)) != 0) {
    ++foreign_;
    return;
  }
  const std::int16_t acc = accumulator_of_id_[frame.can_id & CAN_SFF_MASK];
  if (acc < 0) {
    ++foreign_;
    return;
  }
  accumulators_[static_cast<std::size_t>(acc)].add(frame);
}

BusSample GyroBus::close_samples() {
  BusSample out;
  out.units.reserve(units_.size());
  out.extra_axes.resize(units_.size());
  for (std::size_t i = 0; i < units_.size(); ++i) {
    const std::size_t first = first_of_unit_[i];
    out.units.push_back(accumulators_[first].close());
    for (std::uint8_t k = 1; k < units_[i].axes; ++k) out.extra_axes[i].push_back(accumulators_[first + k].close());
  }
  out.frames_foreign = foreign_;
  foreign_ = 0;
  out.malformed_total = transport_->malformed();
  transport_->sample_closed();
  return out;
}

}  // namespace fogbench::drivers
