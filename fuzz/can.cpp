// Fuzzes the gyro CAN frame codec and the sample accounting (drivers/include/fogbench/drivers/
// can_frame.hpp, sample_accumulator.hpp, docs/can-frames.md). Input:
//   4-byte header: node id (u16 LE, masked into 1..2047), mode (bit 0: increment), unused;
//   then 16-byte records; byte 0 says what the record is:
//     bit 0 clear: a raw frame: can_id (u32 LE) at 1, dlc at 5, data at 6..13
//     bit 0 set:   a GyroFrame to encode: node id at 1..2 (bit 2 of byte 0: use the header's),
//                  counts (i32 LE) at 3..6, sequence at 7, status at 8
//     bit 1 set:   close the sample after this frame.
// Properties: decode(encode(f)) == f; a raw frame that decodes and is in canonical form encodes
// back to the same bytes; the accumulator's counts match AccountingModel's, sample by sample.
#include <cmath>
#include <cstring>
#include <string>

#include "can_model.hpp"

using namespace fogbench;
namespace can = fogbench::drivers::can;

namespace {

std::uint32_t u32(const std::uint8_t* p) {
  return static_cast<std::uint32_t>(p[0]) | static_cast<std::uint32_t>(p[1]) << 8 |
         static_cast<std::uint32_t>(p[2]) << 16 | static_cast<std::uint32_t>(p[3]) << 24;
}
std::uint16_t node_in_range(std::uint16_t v) {
  v &= can::max_node_id;
  return v == 0 ? 1 : v;
}

void check_raw(const ::can_frame& f) {
  const auto d = can::decode(f);
  const bool foreign = (f.can_id & (CAN_EFF_FLAG | CAN_RTR_FLAG | CAN_ERR_FLAG)) != 0;
  if (foreign) {
    FUZZ_CHECK(!d && d.error() == can::DecodeError::not_a_gyro_frame, "a foreign frame (id %#x) decoded", f.can_id);
    return;
  }
  if (!d) {
    (void)can::to_string(d.error());
    return;
  }
  FUZZ_CHECK(f.can_dlc == can::frame_dlc, "decoded with dlc %u", f.can_dlc);
  FUZZ_CHECK(d->node_id == (f.can_id & CAN_SFF_MASK), "node id %u from id %#x", d->node_id, f.can_id);
  (void)can::status_to_string(d->status);
  if (f.can_id >= can::min_node_id && f.can_id <= can::max_node_id && f.data[6] == 0) {
    const ::can_frame e = can::encode(*d);
    FUZZ_CHECK(e.can_id == f.can_id && e.can_dlc == f.can_dlc && std::memcmp(e.data, f.data, 8) == 0,
               "frame of node %u does not encode back to its bytes", d->node_id);
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const bool crc_ok = [] {
    const std::uint8_t check[] = {'1', '2', '3', '4', '5', '6', '7', '8', '9'};
    return can::crc8(check) == 0x4B;
  }();
  FUZZ_CHECK(crc_ok, "CRC-8/SAE-J1850 check value of \"123456789\" is not 0x4B");
  if (size < 4) return 0;

  drivers::GyroChannelConfig config;
  config.node_id = node_in_range(static_cast<std::uint16_t>(data[0] | data[1] << 8));
  if (data[2] & 1) {
    config.mode = drivers::GyroMode::increment;
    config.scale_deg_per_count = 1e-7;
    config.frame_rate_hz = 1000.0;
  } else {
    config.mode = drivers::GyroMode::rate;
    config.scale_dph_per_count = 1e-4;
  }
  drivers::SampleAccumulator acc(config);
  fuzz::AccountingModel model(config.node_id);

  for (std::size_t at = 4; at + 16 <= size; at += 16) {
    const std::uint8_t* r = data + at;
    ::can_frame f;
    std::memset(&f, 0, sizeof f);
    if (r[0] & 1) {
      can::GyroFrame g;
      g.node_id = (r[0] & 4) ? config.node_id : node_in_range(static_cast<std::uint16_t>(r[1] | r[2] << 8));
      g.counts = static_cast<std::int32_t>(u32(r + 3));
      g.sequence = r[7];
      g.status = r[8];
      f = can::encode(g);
      const auto back = can::decode(f);
      FUZZ_CHECK(back.has_value(), "an encoded frame does not decode: %s", std::string(can::to_string(back.error())).c_str());
      FUZZ_CHECK(back->node_id == g.node_id && back->counts == g.counts &&
                     back->sequence == g.sequence && back->status == g.status,
                 "decode(encode(f)) != f for node %u", g.node_id);
    } else {
      f.can_id = u32(r + 1);
      f.can_dlc = r[5];
      std::memcpy(f.data, r + 6, 8);
      check_raw(f);
    }
    acc.add(f);
    model.add(f);
    if (r[0] & 2) {
      const auto s = acc.close();
      model.check_close(s);
      if (s.rate_dph) FUZZ_CHECK(std::isfinite(*s.rate_dph), "rate %g deg/h", *s.rate_dph);
    }
  }
  model.check_close(acc.close());
  return 0;
}
