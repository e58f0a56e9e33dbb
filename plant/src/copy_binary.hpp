// COPY ... FROM STDIN (FORMAT binary) rows for the plant's samples (internal to plant/src).
//
// The binary format (PostgreSQL's "COPY", File Formats): the 11-byte signature "PGCOPY\n\377\r\n\0",
// a 32-bit flags word and a 32-bit header extension length (both 0), then per row a 16-bit field
// count and per field a 32-bit length (-1: NULL) and the value in the type's send format, all
// integers in network byte order and doubles as big-endian IEEE 754; a 16-bit -1 ends the data.
// The server parses no text: float8 and int8 arrive as their bytes (the text format's strtod
// per value was a third of the server's time per row, docs/performance.md).
#pragma once

#include <bit>
#include <cmath>
#include <cstdint>
#include <string>
#include <string_view>

namespace fogbench::plant::detail {

class BinaryCopy {
 public:
  // The signature, flags and header extension: once at the start of the COPY's data.
  void header() { out_.append("PGCOPY\n\377\r\n\0\0\0\0\0\0\0\0\0", 19); }
  // -1 as the field count: once at the end.
  void trailer() { i16(-1); }

  void row(std::int16_t fields) { i16(fields); }
  void null() { i32(-1); }
  void text(std::string_view s) {
    i32(static_cast<std::int32_t>(s.size()));
    out_.append(s);
  }
  void int2(std::int16_t v) {
    i32(2);
    i16(v);
  }
  void int4(std::int32_t v) {
    i32(4);
    i32(v);
  }
  void int8(std::int64_t v) {
    i32(8);
    u64(static_cast<std::uint64_t>(v));
  }
  // A double; NaN or infinite (a signal not read) is NULL, as in the text format.
  void float8(double v) {
    if (!std::isfinite(v)) return null();
    i32(8);
    u64(std::bit_cast<std::uint64_t>(v));
  }

  std::string& data() { return out_; }
  void clear() { out_.clear(); }
  void reserve(std::size_t n) { out_.reserve(n); }

 private:
  void i16(std::int16_t v) {
    const auto u = static_cast<std::uint16_t>(v);
    const char b[2] = {static_cast<char>(u >> 8), static_cast<char>(u)};
    out_.append(b, 2);
  }
  void i32(std::int32_t v) {
    const auto u = static_cast<std::uint32_t>(v);
    const char b[4] = {static_cast<char>(u >> 24), static_cast<char>(u >> 16), static_cast<char>(u >> 8),
                       static_cast<char>(u)};
    out_.append(b, 4);
  }
  void u64(std::uint64_t u) {
    char b[8];
    for (int i = 7; i >= 0; --i) {
      b[i] = static_cast<char>(u);
      u >>= 8;
    }
    out_.append(b, 8);
  }
  std::string out_;
};

}  // namespace fogbench::plant::detail
