// Gyro CAN frame codec and its CRC-8 (layout in docs/can-frames.md).
#include "fogbench/drivers/can_frame.hpp"

#include <cassert>
#include <cstring>
#include <string>

namespace fogbench::drivers::can {
namespace {

constexpr std::array<std::uint8_t, 256> make_crc_table() {
  std::array<std::uint8_t, 256> table{};
  for (unsigned i = 0; i < 256; ++i) {
    auto crc = static_cast<std::uint8_t>(i);
    for (int bit = 0; bit < 8; ++bit) {
      crc = static_cast<std::uint8_t>((crc & 0x80u) ? ((crc << 1) ^ 0x1Du) : (crc << 1));
    }
    table[i] = crc;
  }
  return table;
}

// A table: decoding 64,000 frames/s per bus must stay a small fraction of a core.
constexpr auto crc_table = make_crc_table();

}  // namespace

std::uint8_t crc8(std::span<const std::uint8_t> bytes) noexcept {
  std::uint8_t crc = 0xFF;
  for (std::uint8_t b : bytes) crc = crc_table[crc ^ b];
  return static_cast<std::uint8_t>(crc ^ 0xFFu);
}

std::string status_to_string(std::uint8_t bits) {
  static constexpr std::pair<std::uint8_t, const char*> names[] = {
      {status::valid, "valid"},           {status::light_source_fault, "light_source_fault"},
      {status::over_temperature, "over_temperature"}, {status::loop_fault, "loop_fault"},
      {status::bit_failure, "bit_failure"}, {status::warming_up, "warming_up"},
      {0x40, "bit6"},                     {0x80, "bit7"}};
  std::string out;
  for (auto [mask, name] : names) {
    if (bits & mask) {
      if (!out.empty()) out += '|';
      out += name;
    }
  }
  return out.empty() ? "none" : out;
}

::can_frame encode(const GyroFrame& frame) noexcept {
  assert(frame.node_id >= min_node_id && frame.node_id <= max_node_id);
  ::can_frame out;
  std::memset(&out, 0, sizeof out);
  out.can_id = frame.node_id;
  out.can_dlc = frame_dlc;
  const auto u = static_cast<std::uint32_t>(frame.counts);
  out.data[0] = static_cast<std::uint8_t>(u);
  out.data[1] = static_cast<std::uint8_t>(u >> 8);
  out.data[2] = static_cast<std::uint8_t>(u >> 16);
  out.data[3] = static_cast<std::uint8_t>(u >> 24);
  out.data[4] = frame.sequence;
  out.data[5] = frame.status;
  out.data[6] = 0;
  out.data[7] = crc8(std::span<const std::uint8_t>(out.data, 7));
  return out;
}

std::string_view to_string(DecodeError error) noexcept {
  switch (error) {
    case DecodeError::not_a_gyro_frame: return "not a gyro frame";
    case DecodeError::wrong_dlc: return "wrong DLC";
    case DecodeError::bad_crc: return "bad CRC";
  }
  return "unknown";
}

std::expected<GyroFrame, DecodeError> decode(const ::can_frame& frame) noexcept {
  if (frame.can_id & (CAN_EFF_FLAG | CAN_RTR_FLAG | CAN_ERR_FLAG)) {
    return std::unexpected(DecodeError::not_a_gyro_frame);
  }
  if (frame.can_dlc != frame_dlc) return std::unexpected(DecodeError::wrong_dlc);
  if (crc8(std::span<const std::uint8_t>(frame.data, 7)) != frame.data[7]) {
    return std::unexpected(DecodeError::bad_crc);
  }
  GyroFrame out;
  out.node_id = static_cast<std::uint16_t>(frame.can_id & CAN_SFF_MASK);
  const std::uint32_t u = static_cast<std::uint32_t>(frame.data[0]) |
                          (static_cast<std::uint32_t>(frame.data[1]) << 8) |
                          (static_cast<std::uint32_t>(frame.data[2]) << 16) |
                          (static_cast<std::uint32_t>(frame.data[3]) << 24);
  out.counts = static_cast<std::int32_t>(u);
  out.sequence = frame.data[4];
  out.status = frame.data[5];
  return out;
}

}  // namespace fogbench::drivers::can
