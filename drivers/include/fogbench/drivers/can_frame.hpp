// The gyro's CAN frame (docs/can-frames.md): layout, CRC-8 and codec. Pure: no sockets, no I/O,
// so the mock bench (sim/) encodes the very bytes the drivers decode.
#pragma once

#include <linux/can.h>

#include <array>
#include <cstdint>
#include <expected>
#include <span>
#include <string_view>

namespace fogbench::drivers::can {

// Every gyro frame is a classic data frame with a standard 11-bit identifier equal to the unit's
// node id and exactly 8 data bytes.
inline constexpr std::uint8_t frame_dlc = 8;
inline constexpr std::uint32_t min_node_id = 1;  // 0 is the highest-priority id; kept for buses
inline constexpr std::uint32_t max_node_id = 0x7FF;

// Byte 5 of the frame. A gyro sets `valid` when the rate/increment in the frame is usable; every
// other bit reports a fault or state the operator must see in the sample, so samples OR them.
namespace status {
inline constexpr std::uint8_t valid = 1u << 0;               // measurement usable
inline constexpr std::uint8_t light_source_fault = 1u << 1;  // SLD/ASE source power out of range
inline constexpr std::uint8_t over_temperature = 1u << 2;    // electronics or coil above limit
inline constexpr std::uint8_t loop_fault = 1u << 3;          // closed-loop demodulator not locked
inline constexpr std::uint8_t bit_failure = 1u << 4;         // built-in test failed
inline constexpr std::uint8_t warming_up = 1u << 5;          // start-up, not yet at spec
inline constexpr std::uint8_t reserved_mask = 0xC0;          // bits 6..7 sent as 0
}  // namespace status

// Names of the set status bits, for logs and reports: "valid|over_temperature".
std::string status_to_string(std::uint8_t status_bits);

// The payload of one gyro frame. `counts` is a rate or an angle increment, by the unit's mode.
struct GyroFrame {
  std::uint16_t node_id = 0;
  std::int32_t counts = 0;
  std::uint8_t sequence = 0;  // increments by 1 per frame, wraps 255 -> 0
  std::uint8_t status = 0;
};

// CRC-8/SAE-J1850: polynomial 0x1D, initial value 0xFF, final XOR 0xFF, no reflection.
// Its check value (CRC of the ASCII bytes "123456789") is 0x4B.
std::uint8_t crc8(std::span<const std::uint8_t> bytes) noexcept;

// Encodes a frame byte for byte as a `struct can_frame`: id, dlc 8, data[0..3] counts as
// little-endian int32, data[4] sequence, data[5] status, data[6] 0, data[7] CRC-8 of data[0..6].
// A node id outside 1..2047 is a bug of the caller (asserted).
::can_frame encode(const GyroFrame& frame) noexcept;

enum class DecodeError {
  not_a_gyro_frame,  // extended id, remote request or error frame: not ours, counted as foreign
  wrong_dlc,         // corrupt: a gyro frame always has 8 data bytes
  bad_crc,           // corrupt: byte 7 does not match the CRC of bytes 0..6
};

std::string_view to_string(DecodeError error) noexcept;

// Decodes a frame; the identifier is returned as node_id and not checked against any unit
// (routing and the foreign-id count belong to the caller).
std::expected<GyroFrame, DecodeError> decode(const ::can_frame& frame) noexcept;

}  // namespace fogbench::drivers::can
