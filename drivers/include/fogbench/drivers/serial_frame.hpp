// A gyro's binary frame on a serial line, described by configuration (docs/drivers.md "Serial
// gyros"): sync word, total length, the rate field (offset, type, byte order, scale), an optional
// sequence counter and status byte, and a CRC. Pure: no I/O, so the mock bench (sim/) can encode
// the very bytes the serial transport decodes.
#pragma once

#include <nlohmann/json_fwd.hpp>

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "fogbench/drivers/error.hpp"

namespace fogbench::drivers::serial {

// CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, not reflected, xorout 0); check value 0x29B1.
std::uint16_t crc16_ccitt_false(std::span<const std::uint8_t> bytes) noexcept;
// CRC-16/MODBUS (poly 0x8005 reflected, init 0xFFFF, xorout 0); check value 0x4B37.
std::uint16_t crc16_modbus(std::span<const std::uint8_t> bytes) noexcept;
// CRC-32 (IEEE 802.3, zlib: poly 0x04C11DB7 reflected, init and xorout 0xFFFFFFFF); check 0xCBF43926.
std::uint32_t crc32_ieee(std::span<const std::uint8_t> bytes) noexcept;
// CRC-32/MPEG-2 (poly 0x04C11DB7, init 0xFFFFFFFF, not reflected, xorout 0); check 0x0376E6E7.
// The KVH 1750/1775 IMU's message CRC.
std::uint32_t crc32_mpeg2(std::span<const std::uint8_t> bytes) noexcept;

enum class FieldType { int8, uint8, int16, uint16, int32, uint32, float32, float64 };
enum class ByteOrder { big, little };
enum class CrcKind { none, crc16_ccitt_false, crc16_modbus, crc32_ieee, crc32_mpeg2 };

std::size_t size_of(FieldType type) noexcept;
std::size_t size_of(CrcKind kind) noexcept;
std::string_view to_string(CrcKind kind) noexcept;

struct Field {
  std::size_t offset = 0;  // bytes from the first sync byte
  FieldType type = FieldType::int32;
  ByteOrder order = ByteOrder::big;
};

struct FrameFormat {
  std::vector<std::uint8_t> sync;  // 1..8 bytes at offset 0
  std::size_t length = 0;          // whole frame in bytes, sync and CRC included
  Field rate;
  double rate_scale_dph = 1;       // deg/h per unit of the rate field
  std::optional<Field> sequence;   // an unsigned counter, +1 per frame, wrapping at sequence_modulo
  std::uint64_t sequence_modulo = 256;  // 2..2^bits of the field (2^32 for a whole uint32)
  std::optional<Field> status;     // an unsigned field; a frame is valid when all valid_mask bits are set
  std::uint32_t status_valid_mask = 0;
  CrcKind crc = CrcKind::none;
  std::size_t crc_offset = 0;      // where the CRC is; it covers bytes [crc_from, crc_offset)
  std::size_t crc_from = 0;
  ByteOrder crc_order = ByteOrder::big;
};

// Parses a "frame" object (docs/drivers.md "Serial gyros" lists the keys); every refusal is a
// `config` error naming `path.key` (a field outside the frame, overlapping the sync or the CRC,
// an unknown type, CRC kind or key).
Result<FrameFormat> parse_frame_format(const nlohmann::json& value, const std::string& path);

// What one frame says.
struct Frame {
  double rate_dph = 0;
  std::uint32_t sequence = 0;  // 0 without a sequence field
  std::uint32_t status = 0;    // 0 without a status field
  bool valid = true;           // status & valid_mask == valid_mask (true without a status field)
};

// The bytes of one frame (for the mock bench and tests): the rate is rounded to the field's
// type after dividing by the scale (saturating at its range), the sequence taken modulo the
// counter's, the CRC computed.
std::vector<std::uint8_t> encode(const FrameFormat& format, const Frame& frame);

// One thing the decoder found in the byte stream, in stream order. `offset` counts bytes since
// the decoder was made (where the frame or the garbage began).
struct Event {
  enum class Kind {
    frame,      // a frame whose CRC matched: `frame` holds it
    garbage,    // `bytes` bytes between frames that did not start a frame (skipped)
    bad_crc,    // a whole frame whose CRC did not match (`bytes` = the frame's length)
    cut,        // a frame cut short: the next sync word began `bytes` bytes into it
    bad_value,  // CRC matched but the rate is not a finite number (NaN, inf)
    no_frame,   // `bytes` bytes since the last good frame (or the start) without one: a wrong
                // baud rate, a wrong frame format or a silent gyro talking noise; once per silence
  };
  Kind kind = Kind::frame;
  std::uint64_t offset = 0;
  std::size_t bytes = 0;
  Frame frame;
  // no_frame only: what the `bytes` since the last good frame held, so a wrong baud rate
  // (bytes, never a sync word) is told from a wrong layout or a noisy line (sync words whose
  // frames fail their CRC) and from frames cut short.
  struct Seen {
    std::size_t sync_words = 0;  // frame starts examined: each one a bad_crc, cut or bad_value
    std::size_t bad_crc = 0;
    std::size_t cut = 0;
    std::size_t bad_value = 0;
  } seen;
};

std::string_view to_string(Event::Kind kind) noexcept;
// "bad_crc at byte 1234: CRC of a 36-byte frame does not match", for logs; a no_frame event
// names what was seen and what it suggests.
std::string describe(const Event& event);

// Running totals since the decoder was made.
struct DecoderCounts {
  std::uint64_t frames = 0;          // CRC good
  std::uint64_t corrupt = 0;         // bad_crc + cut + bad_value
  std::uint64_t garbage_bytes = 0;   // skipped between frames
};

// Bytes in, frames and events out. Resynchronises on the sync word after garbage, a cut frame or
// a CRC error; a frame split across feeds is kept until its last byte arrives.
class Decoder {
 public:
  // `no_frame_bytes`: the silence that raises a no_frame event (0: 4 frame lengths, at least 64).
  explicit Decoder(FrameFormat format, std::size_t no_frame_bytes = 0);

  // Appends the events of these bytes to `out`.
  void feed(std::span<const std::uint8_t> bytes, std::vector<Event>& out);

  const DecoderCounts& counts() const noexcept { return counts_; }
  const FrameFormat& format() const noexcept { return format_; }

 private:
  void flush_garbage(std::vector<Event>& out);
  void skipped(std::size_t n, std::vector<Event>& out);

  FrameFormat format_;
  std::size_t no_frame_bytes_;
  std::vector<std::uint8_t> buf_;
  std::size_t pos_ = 0;               // first unexamined byte of buf_
  std::uint64_t buf_offset_ = 0;      // stream offset of buf_[0]
  std::uint64_t garbage_from_ = 0;    // stream offset where the pending garbage run began
  std::size_t garbage_run_ = 0;
  std::size_t since_good_ = 0;        // bytes since the last good frame
  Event::Seen seen_;                  // what those bytes held
  bool silence_reported_ = false;
  DecoderCounts counts_;
};

// Maps a counter of any modulo onto the CAN frame's 8-bit sequence, so SampleAccumulator counts
// lost and repeated serial frames exactly as CAN ones: each step of the source counter (modulo
// its own wrap) advances the 8-bit one by the same step.
class SequenceMapper {
 public:
  explicit SequenceMapper(std::uint64_t modulo) noexcept : modulo_(modulo) {}
  std::uint8_t map(std::uint32_t sequence) noexcept;

 private:
  std::uint64_t modulo_;
  bool have_ = false;
  std::uint64_t last_ = 0;
  std::uint8_t out_ = 0;
};

}  // namespace fogbench::drivers::serial
