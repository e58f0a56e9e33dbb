// The serial gyro frame: CRC check values, the configurable layout and its refusals, and the
// resynchronising decoder (garbage, CRC errors, cut frames, frames split across reads, sequence,
// byte order, scale, a wrong baud rate's noise).
#include <catch2/catch.hpp>

#include <nlohmann/json.hpp>

#include <fstream>
#include <string>
#include <vector>

#include "fogbench/drivers/serial_frame.hpp"

using namespace fogbench::drivers;
using namespace fogbench::drivers::serial;
using nlohmann::json;

namespace {

std::vector<std::uint8_t> bytes_of(std::string_view s) { return {s.begin(), s.end()}; }

json kvh_json() {
  std::ifstream in(FOGBENCH_SOURCE_DIR "/drivers/examples/kvh-1775-format-a.json");
  REQUIRE(in);
  return json::parse(in);
}

FrameFormat kvh() {
  auto f = parse_frame_format(kvh_json(), "frame");
  REQUIRE(f.has_value());
  return *f;
}

// A small integer little-endian format with a CRC-16/MODBUS and a 16-bit counter.
FrameFormat small_le() {
  auto f = parse_frame_format(json::parse(R"({
    "sync": "A55A", "length": 12,
    "rate": {"offset": 2, "type": "int32", "byte_order": "little", "scale_dph": 0.001},
    "sequence": {"offset": 6, "type": "uint16", "byte_order": "little"},
    "status": {"offset": 8, "type": "uint8", "valid_mask": 3},
    "crc": {"kind": "crc16-modbus", "byte_order": "little"}})"), "frame");
  REQUIRE(f.has_value());
  return *f;
}

std::vector<Event> decode_all(Decoder& d, const std::vector<std::uint8_t>& bytes) {
  std::vector<Event> out;
  d.feed(bytes, out);
  return out;
}

std::vector<Event> only(const std::vector<Event>& events, Event::Kind kind) {
  std::vector<Event> out;
  for (const auto& e : events) {
    if (e.kind == kind) out.push_back(e);
  }
  return out;
}

void append(std::vector<std::uint8_t>& to, const std::vector<std::uint8_t>& more) {
  to.insert(to.end(), more.begin(), more.end());
}

}  // namespace

TEST_CASE("serial CRCs give the standard check values of 123456789", "[serial][crc]") {
  const auto check = bytes_of("123456789");
  CHECK(crc16_ccitt_false(check) == 0x29B1);
  CHECK(crc16_modbus(check) == 0x4B37);
  CHECK(crc32_ieee(check) == 0xCBF43926u);
  CHECK(crc32_mpeg2(check) == 0x0376E6E7u);
  CHECK(crc32_ieee({}) == 0u);
}

TEST_CASE("the KVH 1775 example frame parses with its published layout", "[serial][format]") {
  const auto f = kvh();
  CHECK(f.sync == std::vector<std::uint8_t>{0xFE, 0x81, 0xFF, 0x55});
  CHECK(f.length == 36);
  CHECK(f.rate.offset == 4);
  CHECK(f.rate.type == FieldType::float32);
  CHECK(f.sequence_modulo == 128);
  CHECK(f.crc == CrcKind::crc32_mpeg2);
  CHECK(f.crc_offset == 32);
}

TEST_CASE("a frame encodes and decodes in big and little byte order with its scale", "[serial][format]") {
  const auto f = kvh();
  const auto bytes = encode(f, {.rate_dph = 36.0, .sequence = 5, .status = 0x77, .valid = true});
  REQUIRE(bytes.size() == 36);
  CHECK(bytes[0] == 0xFE);
  CHECK(bytes[3] == 0x55);
  // 36 deg/h = 0.01 deg/s as a big-endian float32: 0x3C23D70A.
  CHECK(bytes[4] == 0x3C);
  CHECK(bytes[7] == 0x0A);
  CHECK(bytes[29] == 5);
  Decoder d(f);
  const auto events = decode_all(d, bytes);
  REQUIRE(events.size() == 1);
  REQUIRE(events[0].kind == Event::Kind::frame);
  CHECK(events[0].frame.rate_dph == Approx(36.0).epsilon(1e-6));
  CHECK(events[0].frame.sequence == 5);
  CHECK(events[0].frame.valid);

  const auto le = small_le();
  const auto b2 = encode(le, {.rate_dph = -1.5, .sequence = 0x1234, .status = 3, .valid = true});
  // -1500 counts of 0.001 deg/h, little-endian int32: 24 FA FF FF.
  CHECK(b2[2] == 0x24);
  CHECK(b2[3] == 0xFA);
  CHECK(b2[5] == 0xFF);
  CHECK(b2[6] == 0x34);
  CHECK(b2[7] == 0x12);
  const auto crc = crc16_modbus(std::span<const std::uint8_t>(b2.data(), 10));
  CHECK(b2[10] == (crc & 0xFF));
  CHECK(b2[11] == (crc >> 8));
  Decoder d2(le);
  const auto e2 = decode_all(d2, b2);
  REQUIRE(e2.size() == 1);
  CHECK(e2[0].frame.rate_dph == Approx(-1.5));
  CHECK(e2[0].frame.sequence == 0x1234);
}

TEST_CASE("a status without every valid bit makes the frame not valid", "[serial][format]") {
  const auto le = small_le();
  Decoder d(le);
  const auto e = decode_all(d, encode(le, {.rate_dph = 1, .sequence = 1, .status = 1, .valid = true}));
  REQUIRE(e.size() == 1);
  CHECK_FALSE(e[0].frame.valid);
}

TEST_CASE("garbage between frames is skipped, counted and reported with its offset", "[serial][decoder]") {
  const auto f = kvh();
  std::vector<std::uint8_t> stream;
  append(stream, encode(f, {.rate_dph = 1, .sequence = 0}));
  append(stream, {0x00, 0xFE, 0x81, 0x13, 0x55, 0xFF});  // a sync-like prefix, then not
  append(stream, encode(f, {.rate_dph = 2, .sequence = 1}));
  Decoder d(f);
  const auto events = decode_all(d, stream);
  REQUIRE(events.size() == 3);
  CHECK(events[0].kind == Event::Kind::frame);
  CHECK(events[1].kind == Event::Kind::garbage);
  CHECK(events[1].offset == 36);
  CHECK(events[1].bytes == 6);
  CHECK(events[2].kind == Event::Kind::frame);
  CHECK(events[2].frame.rate_dph == Approx(2));
  CHECK(d.counts().frames == 2);
  CHECK(d.counts().garbage_bytes == 6);
  CHECK(describe(events[1]) == "garbage at byte 36: 6 bytes between frames skipped");
}

TEST_CASE("a CRC error costs one frame and the next one decodes", "[serial][decoder]") {
  const auto f = kvh();
  std::vector<std::uint8_t> stream;
  auto bad = encode(f, {.rate_dph = 1, .sequence = 0});
  bad[10] ^= 0x01;  // one flipped bit in the payload
  append(stream, bad);
  append(stream, encode(f, {.rate_dph = 2, .sequence = 1}));
  Decoder d(f);
  const auto events = decode_all(d, stream);
  REQUIRE(events.size() == 2);
  CHECK(events[0].kind == Event::Kind::bad_crc);
  CHECK(events[0].offset == 0);
  CHECK(events[1].kind == Event::Kind::frame);
  CHECK(d.counts().corrupt == 1);
  CHECK(d.counts().frames == 1);
}

TEST_CASE("a frame cut in half is corrupt and the next frame inside its span decodes", "[serial][decoder]") {
  const auto f = kvh();
  std::vector<std::uint8_t> stream;
  const auto first = encode(f, {.rate_dph = 1, .sequence = 0});
  stream.assign(first.begin(), first.begin() + 18);  // the line drops the rest
  append(stream, encode(f, {.rate_dph = 2, .sequence = 2}));
  Decoder d(f);
  const auto events = decode_all(d, stream);
  REQUIRE(events.size() == 2);
  CHECK(events[0].kind == Event::Kind::cut);
  CHECK(events[0].bytes == 18);
  CHECK(events[1].kind == Event::Kind::frame);
  CHECK(events[1].offset == 18);
  CHECK(events[1].frame.rate_dph == Approx(2));
}

TEST_CASE("a frame split across reads byte by byte decodes once its last byte arrives", "[serial][decoder]") {
  const auto f = kvh();
  std::vector<std::uint8_t> stream = {0x01, 0xFE};  // garbage, then a lone sync byte
  append(stream, encode(f, {.rate_dph = -3, .sequence = 9}));
  Decoder d(f);
  std::vector<Event> events;
  for (const auto b : stream) {
    const std::uint8_t one[] = {b};
    d.feed(one, events);
  }
  REQUIRE(events.size() == 2);
  CHECK(events[0].kind == Event::Kind::garbage);
  CHECK(events[0].bytes == 2);
  CHECK(events[1].kind == Event::Kind::frame);
  CHECK(events[1].offset == 2);
  CHECK(events[1].frame.rate_dph == Approx(-3));
  CHECK(events[1].frame.sequence == 9);
}

TEST_CASE("noise without a frame, as at a wrong baud rate, is reported once as no_frame", "[serial][decoder]") {
  const auto f = kvh();
  Decoder d(f);
  std::vector<std::uint8_t> noise;
  std::uint32_t x = 12345;
  for (int i = 0; i < 1000; ++i) {
    x = x * 1103515245u + 12345u;
    noise.push_back(static_cast<std::uint8_t>(x >> 16));
  }
  const auto events = decode_all(d, noise);
  const auto silent = only(events, Event::Kind::no_frame);
  REQUIRE(silent.size() == 1);
  CHECK(silent[0].bytes >= 144);
  CHECK(describe(silent[0]).find("wrong baud rate") != std::string::npos);
  CHECK(d.counts().frames == 0);
  // A good frame ends the silence; the next silence is reported again.
  std::vector<Event> more;
  d.feed(encode(f, {.rate_dph = 1}), more);
  CHECK(only(more, Event::Kind::frame).size() == 1);
  d.feed(noise, more);
  CHECK(only(more, Event::Kind::no_frame).size() == 1);
}

TEST_CASE("no_frame says what the silence held: never a sync word, CRC failures, cut frames", "[serial][decoder]") {
  const auto f = kvh();
  SECTION("bytes without the sync word: a wrong baud rate or framing") {
    Decoder d(f);
    const std::vector<std::uint8_t> noise(200, 0x5A);
    const auto silent = only(decode_all(d, noise), Event::Kind::no_frame);
    REQUIRE(silent.size() == 1);
    CHECK(silent[0].bytes == 200);  // the run of garbage in one feed
    CHECK(silent[0].seen.sync_words == 0);
    CHECK(describe(silent[0]) ==
          "no_frame at byte 200: no valid frame in 200 bytes received: 0 sync words seen, 0 CRC failures, 0 cut "
          "frames (bytes but never the sync word: a wrong baud rate or framing, or another frame format)");
  }
  SECTION("sync words whose frames fail their CRC: a wrong layout, a near baud rate or noise") {
    Decoder d(f);
    std::vector<std::uint8_t> stream;
    for (std::uint32_t i = 0; i < 5; ++i) {
      auto frame = encode(f, {.rate_dph = 1, .sequence = i});
      frame[35] ^= 0x01;
      stream.insert(stream.end(), frame.begin(), frame.end());
    }
    const auto events = decode_all(d, stream);
    CHECK(only(events, Event::Kind::bad_crc).size() == 5);
    const auto silent = only(events, Event::Kind::no_frame);
    REQUIRE(silent.size() == 1);
    CHECK(silent[0].bytes == 144);  // raised after the 4th frame's 36 bytes
    CHECK(silent[0].seen.sync_words == 4);
    CHECK(silent[0].seen.bad_crc == 4);
    CHECK(silent[0].seen.cut == 0);
    CHECK(describe(silent[0]).find("4 sync words seen, 4 CRC failures, 0 cut frames (sync words but no frame passing its checks") !=
          std::string::npos);
  }
  SECTION("frames cut short: a frame length longer than the gyro's") {
    auto longer = f;
    longer.length = 40;  // the gyro sends 36 bytes, the format says 40 (CRC at 36)
    longer.crc_offset = 36;
    Decoder d(longer);
    std::vector<std::uint8_t> stream;
    for (std::uint32_t i = 0; i < 6; ++i) {
      const auto frame = encode(f, {.rate_dph = 1, .sequence = i});
      stream.insert(stream.end(), frame.begin(), frame.end());
    }
    const auto silent = only(decode_all(d, stream), Event::Kind::no_frame);
    REQUIRE(silent.size() == 1);
    CHECK(silent[0].bytes == 180);  // 4 lengths of 40 bytes: raised at the 5th 36-byte cut
    CHECK(silent[0].seen.cut == 5);
    CHECK(silent[0].seen.bad_crc == 0);
    CHECK(describe(silent[0]).find("(frames cut short by the next sync word") != std::string::npos);
  }
  SECTION("a good frame clears what was seen") {
    Decoder d(f);
    std::vector<std::uint8_t> stream;
    auto bad = encode(f, {.rate_dph = 1, .sequence = 0});
    bad[35] ^= 0x01;
    stream.insert(stream.end(), bad.begin(), bad.end());
    const auto good = encode(f, {.rate_dph = 1, .sequence = 1});
    stream.insert(stream.end(), good.begin(), good.end());
    stream.insert(stream.end(), 200, 0x5A);
    const auto silent = only(decode_all(d, stream), Event::Kind::no_frame);
    REQUIRE(silent.size() == 1);
    CHECK(silent[0].seen.sync_words == 0);
    CHECK(silent[0].seen.bad_crc == 0);
  }
}

TEST_CASE("a NaN rate with a good CRC is corrupt, not a number", "[serial][decoder]") {
  const auto f = kvh();
  Decoder d(f);
  const auto events = decode_all(d, encode(f, {.rate_dph = std::nan("")}));
  REQUIRE(events.size() == 1);
  CHECK(events[0].kind == Event::Kind::bad_value);
  CHECK(d.counts().corrupt == 1);
}

TEST_CASE("the sequence mapper carries gaps of a 7-bit counter onto 8 bits", "[serial][sequence]") {
  SequenceMapper m(128);
  CHECK(m.map(126) == 126);
  CHECK(m.map(127) == 127);
  CHECK(m.map(0) == 128);    // the wrap is a step of 1, not a jump
  CHECK(m.map(3) == 131);    // two lost
  CHECK(m.map(3) == 131);    // a repeat
  CHECK(m.map(2) == 2);      // backwards by one: a step of 127 (131 + 127 wraps to 2)
}

TEST_CASE("a whole uint32 counter wraps as one step, in the format and the mapper", "[serial][sequence]") {
  auto f = parse_frame_format(json::parse(R"({
    "sync": "AA", "length": 11,
    "rate": {"offset": 1, "type": "int16", "scale_dph": 1},
    "sequence": {"offset": 3, "type": "uint32"},
    "crc": {"kind": "crc32"}})"), "frame");
  REQUIRE(f.has_value());
  CHECK(f->sequence_modulo == 4294967296ull);
  Decoder d(*f);
  std::vector<Event> events;
  d.feed(encode(*f, {.rate_dph = 7, .sequence = 0xFFFFFFFFu}), events);
  d.feed(encode(*f, {.rate_dph = 7, .sequence = 0}), events);
  REQUIRE(events.size() == 2);
  CHECK(events[0].frame.sequence == 0xFFFFFFFFu);
  CHECK(events[1].frame.sequence == 0);
  SequenceMapper m(f->sequence_modulo);
  const auto a = m.map(events[0].frame.sequence);
  CHECK(m.map(events[1].frame.sequence) == static_cast<std::uint8_t>(a + 1));
}

TEST_CASE("bad frame layouts are refused naming the key", "[serial][format]") {
  const auto refuse = [](const std::string& patch_json) {
    json j = kvh_json();
    j.merge_patch(json::parse(patch_json));
    auto f = parse_frame_format(j, "gyro_bus.frame");
    REQUIRE_FALSE(f.has_value());
    CHECK(f.error().code == ErrorCode::config);
    return f.error().message;
  };
  CHECK(refuse(R"({"sync": "FE8"})").starts_with("gyro_bus.frame.sync:"));
  CHECK(refuse(R"({"sync": "zz"})").starts_with("gyro_bus.frame.sync:"));
  CHECK(refuse(R"({"length": 4})").starts_with("gyro_bus.frame.length:"));
  CHECK(refuse(R"({"rate": {"offset": 2}})").starts_with("gyro_bus.frame.rate.offset:"));
  CHECK(refuse(R"({"rate": {"offset": 34}})").starts_with("gyro_bus.frame.rate.offset:"));
  CHECK(refuse(R"({"rate": {"type": "float16"}})").starts_with("gyro_bus.frame.rate.type:"));
  CHECK(refuse(R"({"rate": {"byte_order": "middle"}})").starts_with("gyro_bus.frame.rate.byte_order:"));
  CHECK(refuse(R"({"rate": {"scale_dph": 0}})").starts_with("gyro_bus.frame.rate.scale_dph:"));
  CHECK(refuse(R"({"rate": {"offset": 30}})").starts_with("gyro_bus.frame.rate.offset:"));  // overlaps the CRC
  CHECK(refuse(R"({"sequence": {"type": "float32"}})").starts_with("gyro_bus.frame.sequence.type:"));
  CHECK(refuse(R"({"sequence": {"modulo": 300}})").starts_with("gyro_bus.frame.sequence.modulo:"));
  CHECK(refuse(R"({"status": {"valid_mask": 256}})").starts_with("gyro_bus.frame.status.valid_mask:"));
  CHECK(refuse(R"({"crc": {"kind": "crc8"}})").starts_with("gyro_bus.frame.crc.kind:"));
  CHECK(refuse(R"({"crc": {"offset": 34}})").starts_with("gyro_bus.frame.crc.offset:"));
  CHECK(refuse(R"({"crc": {"from": 32}})").starts_with("gyro_bus.frame.crc.from:"));
  CHECK(refuse(R"({"scael": 1})").starts_with("gyro_bus.frame"));
  json j = kvh_json();
  j.erase("crc");
  CHECK(parse_frame_format(j, "f").error().message.starts_with("f.crc: missing"));
}
