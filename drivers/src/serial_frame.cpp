// Serial gyro frames: CRCs, the configurable layout, its JSON, the encoder and the resynchronising
// decoder.
#include "fogbench/drivers/serial_frame.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <bit>
#include <cctype>
#include <cmath>
#include <cstring>
#include <limits>
#include <utility>

#include "json_fields.hpp"

namespace fogbench::drivers::serial {

using nlohmann::json;

std::uint16_t crc16_ccitt_false(std::span<const std::uint8_t> bytes) noexcept {
  std::uint16_t crc = 0xFFFF;
  for (const auto b : bytes) {
    crc = static_cast<std::uint16_t>(crc ^ (b << 8));
    for (int i = 0; i < 8; ++i) {
      crc = static_cast<std::uint16_t>((crc & 0x8000) ? (crc << 1) ^ 0x1021 : crc << 1);
    }
  }
  return crc;
}

std::uint16_t crc16_modbus(std::span<const std::uint8_t> bytes) noexcept {
  std::uint16_t crc = 0xFFFF;
  for (const auto b : bytes) {
    crc = static_cast<std::uint16_t>(crc ^ b);
    for (int i = 0; i < 8; ++i) {
      crc = static_cast<std::uint16_t>((crc & 1) ? (crc >> 1) ^ 0xA001 : crc >> 1);
    }
  }
  return crc;
}

namespace {

struct Crc32Tables {
  std::uint32_t reflected[256];
  std::uint32_t normal[256];
  constexpr Crc32Tables() : reflected{}, normal{} {
    for (std::uint32_t i = 0; i < 256; ++i) {
      std::uint32_t r = i;
      std::uint32_t n = i << 24;
      for (int k = 0; k < 8; ++k) {
        r = (r & 1) ? (r >> 1) ^ 0xEDB88320u : r >> 1;
        n = (n & 0x80000000u) ? (n << 1) ^ 0x04C11DB7u : n << 1;
      }
      reflected[i] = r;
      normal[i] = n;
    }
  }
};
constexpr Crc32Tables crc32_tables;

}  // namespace

std::uint32_t crc32_ieee(std::span<const std::uint8_t> bytes) noexcept {
  std::uint32_t crc = 0xFFFFFFFFu;
  for (const auto b : bytes) crc = (crc >> 8) ^ crc32_tables.reflected[(crc ^ b) & 0xFF];
  return crc ^ 0xFFFFFFFFu;
}

std::uint32_t crc32_mpeg2(std::span<const std::uint8_t> bytes) noexcept {
  std::uint32_t crc = 0xFFFFFFFFu;
  for (const auto b : bytes) crc = (crc << 8) ^ crc32_tables.normal[((crc >> 24) ^ b) & 0xFF];
  return crc;
}

std::size_t size_of(FieldType type) noexcept {
  switch (type) {
    case FieldType::int8: case FieldType::uint8: return 1;
    case FieldType::int16: case FieldType::uint16: return 2;
    case FieldType::int32: case FieldType::uint32: case FieldType::float32: return 4;
    case FieldType::float64: return 8;
  }
  return 0;
}

std::size_t size_of(CrcKind kind) noexcept {
  switch (kind) {
    case CrcKind::none: return 0;
    case CrcKind::crc16_ccitt_false: case CrcKind::crc16_modbus: return 2;
    case CrcKind::crc32_ieee: case CrcKind::crc32_mpeg2: return 4;
  }
  return 0;
}

std::string_view to_string(CrcKind kind) noexcept {
  switch (kind) {
    case CrcKind::none: return "none";
    case CrcKind::crc16_ccitt_false: return "crc16-ccitt-false";
    case CrcKind::crc16_modbus: return "crc16-modbus";
    case CrcKind::crc32_ieee: return "crc32";
    case CrcKind::crc32_mpeg2: return "crc32-mpeg2";
  }
  return "?";
}

namespace {

std::uint64_t read_raw(const std::uint8_t* p, std::size_t n, ByteOrder order) noexcept {
  std::uint64_t v = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint8_t b = order == ByteOrder::big ? p[i] : p[n - 1 - i];
    v = (v << 8) | b;
  }
  return v;
}

void write_raw(std::uint8_t* p, std::size_t n, ByteOrder order, std::uint64_t v) noexcept {
  for (std::size_t i = 0; i < n; ++i) {
    const auto b = static_cast<std::uint8_t>(v >> (8 * (n - 1 - i)));
    p[order == ByteOrder::big ? i : n - 1 - i] = b;
  }
}

double read_value(const std::uint8_t* frame, const Field& f) noexcept {
  const auto raw = read_raw(frame + f.offset, size_of(f.type), f.order);
  switch (f.type) {
    case FieldType::int8: return static_cast<std::int8_t>(raw);
    case FieldType::uint8: return static_cast<double>(raw);
    case FieldType::int16: return static_cast<std::int16_t>(raw);
    case FieldType::uint16: return static_cast<double>(raw);
    case FieldType::int32: return static_cast<std::int32_t>(raw);
    case FieldType::uint32: return static_cast<double>(raw);
    case FieldType::float32: return std::bit_cast<float>(static_cast<std::uint32_t>(raw));
    case FieldType::float64: return std::bit_cast<double>(raw);
  }
  return 0;
}

void write_value(std::uint8_t* frame, const Field& f, double value) noexcept {
  const auto n = size_of(f.type);
  const auto integer = [&](double lo, double hi) {
    const double r = std::nearbyint(std::clamp(std::isnan(value) ? 0.0 : value, lo, hi));
    return static_cast<std::uint64_t>(static_cast<std::int64_t>(r));
  };
  std::uint64_t raw = 0;
  switch (f.type) {
    case FieldType::int8: raw = integer(-128, 127); break;
    case FieldType::uint8: raw = integer(0, 255); break;
    case FieldType::int16: raw = integer(-32768, 32767); break;
    case FieldType::uint16: raw = integer(0, 65535); break;
    case FieldType::int32: raw = integer(-2147483648.0, 2147483647.0); break;
    case FieldType::uint32: raw = integer(0, 4294967295.0); break;
    case FieldType::float32: raw = std::bit_cast<std::uint32_t>(static_cast<float>(value)); break;
    case FieldType::float64: raw = std::bit_cast<std::uint64_t>(value); break;
  }
  write_raw(frame + f.offset, n, f.order, raw);
}

std::uint32_t compute_crc(const FrameFormat& f, const std::uint8_t* frame) noexcept {
  const std::span<const std::uint8_t> covered(frame + f.crc_from, f.crc_offset - f.crc_from);
  switch (f.crc) {
    case CrcKind::none: return 0;
    case CrcKind::crc16_ccitt_false: return crc16_ccitt_false(covered);
    case CrcKind::crc16_modbus: return crc16_modbus(covered);
    case CrcKind::crc32_ieee: return crc32_ieee(covered);
    case CrcKind::crc32_mpeg2: return crc32_mpeg2(covered);
  }
  return 0;
}

bool crc_matches(const FrameFormat& f, const std::uint8_t* frame) noexcept {
  if (f.crc == CrcKind::none) return true;
  return read_raw(frame + f.crc_offset, size_of(f.crc), f.crc_order) == compute_crc(f, frame);
}

Frame decode_frame(const FrameFormat& f, const std::uint8_t* p) noexcept {
  Frame out;
  out.rate_dph = read_value(p, f.rate) * f.rate_scale_dph;
  if (f.sequence) out.sequence = static_cast<std::uint32_t>(static_cast<std::uint64_t>(read_value(p, *f.sequence)) % f.sequence_modulo);
  if (f.status) {
    out.status = static_cast<std::uint32_t>(read_value(p, *f.status));
    out.valid = (out.status & f.status_valid_mask) == f.status_valid_mask;
  }
  return out;
}

// --- JSON ---------------------------------------------------------------------------------

using detail::config_error;
using detail::join_path;

#define SERIAL_TRY(var, expr) \
  auto var = (expr);            \
  if (!var) return std::unexpected(var.error())

Result<FieldType> parse_type(const json& obj, const std::string& path, bool integer_only) {
  SERIAL_TRY(name, detail::get_string(obj, path, "type"));
  static constexpr std::pair<std::string_view, FieldType> types[] = {
      {"int8", FieldType::int8},       {"uint8", FieldType::uint8},     {"int16", FieldType::int16},
      {"uint16", FieldType::uint16},   {"int32", FieldType::int32},     {"uint32", FieldType::uint32},
      {"float32", FieldType::float32}, {"float64", FieldType::float64}};
  for (const auto& [n, t] : types) {
    if (*name != n) continue;
    if (integer_only && (t == FieldType::float32 || t == FieldType::float64 || t == FieldType::int8 ||
                         t == FieldType::int16 || t == FieldType::int32)) {
      return config_error(join_path(path, "type"),
                          "expected an unsigned integer type uint8, uint16 or uint32 (got '" + *name + "')");
    }
    return t;
  }
  return config_error(join_path(path, "type"),
                      "unknown type '" + *name +
                          "' (expected int8, uint8, int16, uint16, int32, uint32, float32 or float64)");
}

Result<ByteOrder> parse_order(const json& obj, const std::string& path) {
  SERIAL_TRY(name, detail::get_string_or(obj, path, "byte_order", "big"));
  if (*name == "big") return ByteOrder::big;
  if (*name == "little") return ByteOrder::little;
  return config_error(join_path(path, "byte_order"), "expected 'big' or 'little' (got '" + *name + "')");
}

// A field inside the frame, after the sync word and before the CRC (when the CRC is at the end
// it is checked separately: here only against the frame and the sync).
Result<Field> parse_field(const json& obj, const std::string& path, std::size_t length,
                          std::size_t sync_len, bool integer_only,
                          std::initializer_list<std::string_view> extra_keys) {
  if (auto ok = detail::expect_object(obj, path); !ok) return std::unexpected(ok.error());
  std::vector<std::string_view> known{"offset", "type", "byte_order"};
  known.insert(known.end(), extra_keys.begin(), extra_keys.end());
  if (auto ok = detail::expect_known_keys(obj, path, std::span<const std::string_view>(known)); !ok) {
    return std::unexpected(ok.error());
  }
  Field f;
  SERIAL_TRY(type, parse_type(obj, path, integer_only));
  f.type = *type;
  SERIAL_TRY(order, parse_order(obj, path));
  f.order = *order;
  SERIAL_TRY(offset, detail::get_int(obj, path, "offset", 0, 4095));
  f.offset = static_cast<std::size_t>(*offset);
  if (f.offset < sync_len || f.offset + size_of(f.type) > length) {
    return config_error(join_path(path, "offset"),
                        "a " + std::to_string(size_of(f.type)) + "-byte field at " + std::to_string(f.offset) +
                            " is not inside the frame after the sync word (bytes " + std::to_string(sync_len) +
                            ".." + std::to_string(length - 1) + ")");
  }
  return f;
}

bool overlaps(const Field& a, std::size_t from, std::size_t n) {
  return a.offset < from + n && from < a.offset + size_of(a.type);
}

}  // namespace

Result<FrameFormat> parse_frame_format(const json& value, const std::string& path) {
  if (auto ok = detail::expect_object(value, path); !ok) return std::unexpected(ok.error());
  if (auto ok = detail::expect_known_keys(value, path,
                                          {"sync", "length", "rate", "sequence", "status", "crc", "source"});
      !ok) {
    return std::unexpected(ok.error());
  }
  FrameFormat f;
  SERIAL_TRY(sync, detail::get_string(value, path, "sync"));
  const std::string& hex = *sync;
  const auto is_hex = [](char c) { return std::isxdigit(static_cast<unsigned char>(c)) != 0; };
  if (hex.empty() || hex.size() % 2 != 0 || hex.size() > 16 || !std::all_of(hex.begin(), hex.end(), is_hex)) {
    return config_error(join_path(path, "sync"),
                        "expected 1..8 bytes as an even number of hex digits, e.g. \"FE81FF55\" (got \"" + hex + "\")");
  }
  for (std::size_t i = 0; i < hex.size(); i += 2) {
    f.sync.push_back(static_cast<std::uint8_t>(std::stoul(hex.substr(i, 2), nullptr, 16)));
  }
  SERIAL_TRY(length, detail::get_int(value, path, "length", 2, 4096));
  f.length = static_cast<std::size_t>(*length);
  if (f.length <= f.sync.size()) {
    return config_error(join_path(path, "length"), "the frame must be longer than its sync word");
  }
  if (!value.contains("rate")) return config_error(join_path(path, "rate"), "missing (expected an object)");
  const auto rp = join_path(path, "rate");
  SERIAL_TRY(rate, parse_field(value["rate"], rp, f.length, f.sync.size(), false, {"scale_dph"}));
  f.rate = *rate;
  SERIAL_TRY(scale, detail::get_number(value["rate"], rp, "scale_dph"));
  if (!std::isfinite(*scale) || *scale == 0) {
    return config_error(join_path(rp, "scale_dph"), "expected a finite, non-zero number of deg/h per unit");
  }
  f.rate_scale_dph = *scale;
  if (value.contains("sequence")) {
    const auto sp = join_path(path, "sequence");
    SERIAL_TRY(seq, parse_field(value["sequence"], sp, f.length, f.sync.size(), true, {"modulo"}));
    f.sequence = *seq;
    const auto max_mod = std::int64_t{1} << (8 * size_of(seq->type));
    SERIAL_TRY(mod, detail::get_int_or(value["sequence"], sp, "modulo", 2, max_mod, max_mod));
    f.sequence_modulo = static_cast<std::uint64_t>(*mod);
  }
  if (value.contains("status")) {
    const auto sp = join_path(path, "status");
    SERIAL_TRY(st, parse_field(value["status"], sp, f.length, f.sync.size(), true, {"valid_mask"}));
    f.status = *st;
    SERIAL_TRY(mask, detail::get_int_or(value["status"], sp, "valid_mask", 0, 0xFFFFFFFF, 0));
    f.status_valid_mask = static_cast<std::uint32_t>(*mask);
    if (size_of(st->type) < 4 && f.status_valid_mask >> (8 * size_of(st->type)) != 0) {
      return config_error(join_path(sp, "valid_mask"), "has bits outside the status field");
    }
  }
  if (!value.contains("crc")) {
    return config_error(join_path(path, "crc"), "missing (expected an object; {\"kind\": \"none\"} for a frame without one)");
  }
  const auto cp = join_path(path, "crc");
  const json& c = value["crc"];
  if (auto ok = detail::expect_object(c, cp); !ok) return std::unexpected(ok.error());
  if (auto ok = detail::expect_known_keys(c, cp, {"kind", "offset", "from", "byte_order"}); !ok) {
    return std::unexpected(ok.error());
  }
  SERIAL_TRY(kind, detail::get_string(c, cp, "kind"));
  bool found = false;
  for (auto k : {CrcKind::none, CrcKind::crc16_ccitt_false, CrcKind::crc16_modbus, CrcKind::crc32_ieee,
                 CrcKind::crc32_mpeg2}) {
    if (*kind == to_string(k)) {
      f.crc = k;
      found = true;
    }
  }
  if (!found) {
    return config_error(join_path(cp, "kind"), "unknown CRC '" + *kind +
                                                   "' (expected none, crc16-ccitt-false, crc16-modbus, crc32 or crc32-mpeg2)");
  }
  if (f.crc != CrcKind::none) {
    const auto n = size_of(f.crc);
    SERIAL_TRY(off, detail::get_int_or(c, cp, "offset", 0, 4095, static_cast<std::int64_t>(f.length - n)));
    f.crc_offset = static_cast<std::size_t>(*off);
    if (f.crc_offset < f.sync.size() || f.crc_offset + n > f.length) {
      return config_error(join_path(cp, "offset"), "a " + std::to_string(n) + "-byte CRC at " +
                                                       std::to_string(f.crc_offset) + " is not inside the frame after the sync word");
    }
    SERIAL_TRY(from, detail::get_int_or(c, cp, "from", 0, 4095, 0));
    f.crc_from = static_cast<std::size_t>(*from);
    if (f.crc_from >= f.crc_offset) {
      return config_error(join_path(cp, "from"), "the CRC must cover at least one byte before it (from < offset)");
    }
    SERIAL_TRY(order, parse_order(c, cp));
    f.crc_order = *order;
    const std::pair<const char*, const std::optional<Field>*> fields[] = {
        {"rate", nullptr}, {"sequence", &f.sequence}, {"status", &f.status}};
    for (const auto& [name, opt] : fields) {
      const Field* fld = opt ? (opt->has_value() ? &**opt : nullptr) : &f.rate;
      if (fld && overlaps(*fld, f.crc_offset, n)) {
        return config_error(join_path(join_path(path, name), "offset"), "overlaps the CRC at " + std::to_string(f.crc_offset));
      }
    }
  }
  return f;
}

std::vector<std::uint8_t> encode(const FrameFormat& format, const Frame& frame) {
  std::vector<std::uint8_t> out(format.length, 0);
  std::copy(format.sync.begin(), format.sync.end(), out.begin());
  write_value(out.data(), format.rate, frame.rate_dph / format.rate_scale_dph);
  if (format.sequence) write_value(out.data(), *format.sequence, static_cast<double>(frame.sequence % format.sequence_modulo));
  if (format.status) write_value(out.data(), *format.status, frame.status);
  if (format.crc != CrcKind::none) {
    write_raw(out.data() + format.crc_offset, size_of(format.crc), format.crc_order, compute_crc(format, out.data()));
  }
  return out;
}

std::string_view to_string(Event::Kind kind) noexcept {
  switch (kind) {
    case Event::Kind::frame: return "frame";
    case Event::Kind::garbage: return "garbage";
    case Event::Kind::bad_crc: return "bad_crc";
    case Event::Kind::cut: return "cut";
    case Event::Kind::bad_value: return "bad_value";
    case Event::Kind::no_frame: return "no_frame";
  }
  return "?";
}

std::string describe(const Event& e) {
  std::string out(to_string(e.kind));
  out += " at byte " + std::to_string(e.offset);
  switch (e.kind) {
    case Event::Kind::frame: break;
    case Event::Kind::garbage: out += ": " + std::to_string(e.bytes) + " bytes between frames skipped"; break;
    case Event::Kind::bad_crc: out += ": CRC of a " + std::to_string(e.bytes) + "-byte frame does not match"; break;
    case Event::Kind::cut:
      out += ": frame cut short, the next sync word began " + std::to_string(e.bytes) + " bytes into it";
      break;
    case Event::Kind::bad_value: out += ": CRC matched but the rate is not a finite number"; break;
    case Event::Kind::no_frame: {
      const auto& s = e.seen;
      out += ": no valid frame in " + std::to_string(e.bytes) + " bytes received: " + std::to_string(s.sync_words) +
             " sync words seen, " + std::to_string(s.bad_crc) + " CRC failures, " + std::to_string(s.cut) +
             " cut frames";
      if (s.bad_value > 0) out += ", " + std::to_string(s.bad_value) + " non-finite rates";
      if (s.sync_words == 0) {
        out += " (bytes but never the sync word: a wrong baud rate or framing, or another frame format)";
      } else if (s.bad_crc + s.bad_value > 0) {
        out += " (sync words but no frame passing its checks: a wrong CRC or layout in the frame format, "
               "a baud rate close to the gyro's, or noise on the line)";
      } else {
        out += " (frames cut short by the next sync word: a frame length longer than the gyro's, or bytes dropped)";
      }
      break;
    }
  }
  return out;
}

Decoder::Decoder(FrameFormat format, std::size_t no_frame_bytes)
    : format_(std::move(format)),
      no_frame_bytes_(no_frame_bytes ? no_frame_bytes : std::max<std::size_t>(64, 4 * format_.length)) {}

void Decoder::flush_garbage(std::vector<Event>& out) {
  if (garbage_run_ == 0) return;
  Event e;
  e.kind = Event::Kind::garbage;
  e.offset = garbage_from_;
  e.bytes = garbage_run_;
  out.push_back(e);
  garbage_run_ = 0;
}

void Decoder::skipped(std::size_t n, std::vector<Event>& out) {
  since_good_ += n;
  if (!silence_reported_ && since_good_ >= no_frame_bytes_) {
    silence_reported_ = true;
    Event e;
    e.kind = Event::Kind::no_frame;
    e.offset = buf_offset_ + pos_;
    e.bytes = since_good_;
    e.seen = seen_;
    out.push_back(e);
  }
}

void Decoder::feed(std::span<const std::uint8_t> bytes, std::vector<Event>& out) {
  buf_.insert(buf_.end(), bytes.begin(), bytes.end());
  const auto& sync = format_.sync;
  const std::size_t len = format_.length;
  while (pos_ < buf_.size()) {
    // The next sync word at or after pos_ (possibly only its beginning at the end of the buffer).
    auto it = std::search(buf_.begin() + static_cast<std::ptrdiff_t>(pos_), buf_.end(), sync.begin(), sync.end());
    std::size_t at = static_cast<std::size_t>(it - buf_.begin());
    if (it == buf_.end()) {
      // Keep a tail that may be the start of a sync word split across feeds.
      std::size_t keep = 0;
      for (std::size_t k = std::min(sync.size() - 1, buf_.size() - pos_); k > 0; --k) {
        if (std::equal(buf_.end() - static_cast<std::ptrdiff_t>(k), buf_.end(), sync.begin())) {
          keep = k;
          break;
        }
      }
      at = buf_.size() - keep;
    }
    if (at > pos_) {
      if (garbage_run_ == 0) garbage_from_ = buf_offset_ + pos_;
      garbage_run_ += at - pos_;
      counts_.garbage_bytes += at - pos_;
      const std::size_t n = at - pos_;
      pos_ = at;
      skipped(n, out);
    }
    if (it == buf_.end() || buf_.size() - pos_ < len) break;  // wait for more bytes
    const std::uint8_t* p = buf_.data() + pos_;
    const std::uint64_t offset = buf_offset_ + pos_;
    if (crc_matches(format_, p)) {
      flush_garbage(out);
      Event e;
      e.offset = offset;
      e.bytes = len;
      e.frame = decode_frame(format_, p);
      const bool bad = !std::isfinite(e.frame.rate_dph);
      if (bad) {
        e.kind = Event::Kind::bad_value;
        ++counts_.corrupt;
        ++seen_.sync_words;
        ++seen_.bad_value;
      } else {
        ++counts_.frames;
        since_good_ = 0;
        seen_ = {};
        silence_reported_ = false;
      }
      out.push_back(e);
      pos_ += len;
      if (bad) skipped(len, out);
      continue;
    }
    flush_garbage(out);
    // A frame cut short shows the next sync word inside it; resynchronise there. Otherwise the
    // whole frame is corrupt: no frame can begin inside it, since no sync word does.
    auto next = std::search(buf_.begin() + static_cast<std::ptrdiff_t>(pos_ + 1),
                            buf_.begin() + static_cast<std::ptrdiff_t>(pos_ + len), sync.begin(), sync.end());
    Event e;
    e.offset = offset;
    std::size_t step = len;
    if (next != buf_.begin() + static_cast<std::ptrdiff_t>(pos_ + len)) {
      step = static_cast<std::size_t>(next - buf_.begin()) - pos_;
      e.kind = Event::Kind::cut;
      ++seen_.cut;
    } else {
      e.kind = Event::Kind::bad_crc;
      ++seen_.bad_crc;
    }
    ++seen_.sync_words;
    e.bytes = step;
    ++counts_.corrupt;
    out.push_back(e);
    pos_ += step;
    skipped(step, out);
  }
  // Drop what has been examined.
  if (pos_ > 0) {
    buf_.erase(buf_.begin(), buf_.begin() + static_cast<std::ptrdiff_t>(pos_));
    buf_offset_ += pos_;
    pos_ = 0;
  }
}

std::uint8_t SequenceMapper::map(std::uint32_t sequence) noexcept {
  const std::uint64_t seq = sequence % modulo_;
  if (!have_) {
    have_ = true;
    out_ = static_cast<std::uint8_t>(seq);
  } else {
    const std::uint64_t step = (seq + modulo_ - last_) % modulo_;
    out_ = static_cast<std::uint8_t>(out_ + step);
  }
  last_ = seq;
  return out_;
}

#undef SERIAL_TRY

}  // namespace fogbench::drivers::serial
