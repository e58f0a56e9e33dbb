// Averaging gyro frames into samples and the accounting of lost, corrupt, foreign and repeated
// frames.
#include <catch2/catch.hpp>

#include <limits>

#include "fogbench/drivers/can_frame.hpp"
#include "fogbench/drivers/sample_accumulator.hpp"

using namespace fogbench::drivers;

namespace {

constexpr std::uint16_t id = 0x101;
constexpr std::uint8_t ok = can::status::valid;

GyroChannelConfig rate_unit() {
  GyroChannelConfig c;
  c.node_id = id;
  c.mode = GyroMode::rate;
  c.scale_dph_per_count = 0.001;  // 1 count = 0.001 deg/h
  return c;
}

can_frame frame(std::uint8_t seq, std::int32_t counts, std::uint8_t status = ok) {
  return can::encode({id, counts, seq, status});
}

}  // namespace

TEST_CASE("a sample's rate is the mean of its frames times the scale") {
  SampleAccumulator acc(rate_unit());
  // counts 1000, 2000, 3000, 6000: mean 3000 counts * 0.001 deg/h = 3.0 deg/h.
  acc.add(frame(0, 1000));
  acc.add(frame(1, 2000));
  acc.add(frame(2, 3000));
  acc.add(frame(3, 6000));
  const GyroSample s = acc.close();
  CHECK(s.node_id == id);
  CHECK(s.frames == 4);
  CHECK(s.frames_used == 4);
  CHECK(s.frames_lost == 0);
  CHECK(s.sum_counts == 12000);
  REQUIRE(s.rate_dph.has_value());
  CHECK(*s.rate_dph == Approx(3.0).epsilon(1e-12));
  CHECK(s.status_or == ok);
}

TEST_CASE("closing resets the counts and starts an empty sample") {
  SampleAccumulator acc(rate_unit());
  acc.add(frame(0, 10));
  (void)acc.close();
  const GyroSample empty = acc.close();
  CHECK(empty.frames == 0);
  CHECK(empty.sum_counts == 0);
  CHECK_FALSE(empty.rate_dph.has_value());  // no frame: no rate, not 0 deg/h
}

TEST_CASE("increment mode: mean increment per frame times the frame rate") {
  GyroChannelConfig c;
  c.node_id = id;
  c.mode = GyroMode::increment;
  c.scale_deg_per_count = 1e-6;  // 1 count = 1e-6 deg
  c.frame_rate_hz = 1000;
  SampleAccumulator acc(c);
  // Mean increment 5 counts = 5e-6 deg per frame; at 1000 frames/s that is 5e-3 deg/s,
  // times 3600 s/h = 18 deg/h. The lost frame (sequence 2) does not bias the mean.
  acc.add(frame(0, 4));
  acc.add(frame(1, 6));
  acc.add(frame(3, 5));
  const GyroSample s = acc.close();
  CHECK(s.frames_lost == 1);
  REQUIRE(s.rate_dph.has_value());
  CHECK(*s.rate_dph == Approx(18.0).epsilon(1e-12));
}

TEST_CASE("a skipped sequence number counts as one lost frame") {
  SampleAccumulator acc(rate_unit());
  acc.add(frame(10, 1));
  acc.add(frame(11, 1));
  acc.add(frame(13, 1));  // 12 missing
  acc.add(frame(17, 1));  // 14, 15, 16 missing
  const GyroSample s = acc.close();
  CHECK(s.frames == 4);
  CHECK(s.frames_lost == 1 + 3);
}

TEST_CASE("the sequence wraps from 255 to 0 without a loss") {
  SampleAccumulator acc(rate_unit());
  acc.add(frame(254, 1));
  acc.add(frame(255, 1));
  acc.add(frame(0, 1));
  acc.add(frame(1, 1));
  CHECK(acc.close().frames_lost == 0);
  // 254 -> 1 across the wrap: 255 and 0 missing, (1 - 254 - 1) mod 256 = 2.
  SampleAccumulator gap(rate_unit());
  gap.add(frame(254, 1));
  gap.add(frame(1, 1));
  CHECK(gap.close().frames_lost == 2);
}

TEST_CASE("sequence tracking continues across a sample boundary") {
  SampleAccumulator acc(rate_unit());
  acc.add(frame(100, 1));
  (void)acc.close();
  acc.add(frame(102, 1));  // 101 was lost between the samples: counted in the second
  const GyroSample s = acc.close();
  CHECK(s.frames_lost == 1);
}

TEST_CASE("a corrupt frame is counted as corrupt and not again as lost") {
  SampleAccumulator acc(rate_unit());
  acc.add(frame(0, 100));
  can_frame bad = frame(1, 100);
  bad.data[2] ^= 0x10;  // a flipped bit: CRC fails
  acc.add(bad);
  can_frame short_frame = frame(2, 100);
  short_frame.can_dlc = 6;  // wrong DLC
  acc.add(short_frame);
  acc.add(frame(3, 100));
  acc.add(frame(5, 100));  // 4 really missing
  const GyroSample s = acc.close();
  CHECK(s.frames == 3);
  CHECK(s.frames_corrupt == 2);
  // Gaps: 0->3 is 2 frames, both explained by the corrupt ones; 3->5 is 1, unexplained.
  CHECK(s.frames_lost == 1);
  // The corrupt frames' counts are not averaged: mean of three 100s.
  CHECK(s.sum_counts == 300);
}

TEST_CASE("foreign ids, extended and remote frames are counted as foreign") {
  SampleAccumulator acc(rate_unit());
  acc.add(frame(0, 1));
  acc.add(can::encode({0x102, 1, 1, ok}));  // another unit's id
  can_frame ext = frame(1, 1);
  ext.can_id |= CAN_EFF_FLAG;  // same low bits, but an extended id
  acc.add(ext);
  can_frame rtr = frame(1, 1);
  rtr.can_id |= CAN_RTR_FLAG;
  acc.add(rtr);
  const GyroSample s = acc.close();
  CHECK(s.frames == 1);
  CHECK(s.frames_foreign == 3);
  CHECK(s.frames_corrupt == 0);
}

TEST_CASE("frames without the valid bit are counted but not averaged, and status bits are ORed") {
  SampleAccumulator acc(rate_unit());
  acc.add(frame(0, 1000, ok));
  acc.add(frame(1, 999999, can::status::light_source_fault));  // not valid
  acc.add(frame(2, 3000, ok | can::status::warming_up));
  const GyroSample s = acc.close();
  CHECK(s.frames == 3);
  CHECK(s.frames_used == 2);
  REQUIRE(s.rate_dph.has_value());
  CHECK(*s.rate_dph == Approx(2.0));  // (1000 + 3000) / 2 * 0.001
  CHECK(s.status_or == (ok | can::status::light_source_fault | can::status::warming_up));
}

TEST_CASE("a repeated sequence number is counted and not averaged twice") {
  SampleAccumulator acc(rate_unit());
  acc.add(frame(7, 1000));
  acc.add(frame(7, 1000));
  acc.add(frame(8, 1000));
  const GyroSample s = acc.close();
  CHECK(s.frames_repeated == 1);
  CHECK(s.frames_used == 2);
  CHECK(s.frames_lost == 0);
}

TEST_CASE("a power-on is a frame that says so: warming_up rising or the counter back at 0 while warming up") {
  SampleAccumulator acc(rate_unit());
  constexpr std::uint8_t warm = ok | can::status::warming_up;
  SECTION("a running gyro's frames, however late, bunched or lost, start nothing") {
    // The reader's timing cannot show in the frames: the counter runs on and no warming_up.
    for (int s = 0; s < 600; ++s) acc.add(frame(static_cast<std::uint8_t>(s), 1000));
    CHECK(acc.close().starts == 0);
    CHECK(acc.close().starts == 0);  // a period with no frame at all (a paused reader)
    acc.add(frame(0, 1000));         // 600 mod 256 = 88 was next: frames lost up to 255, then 0
    CHECK(acc.close().starts == 0);  // lost frames are lost, not a power cycle
  }
  SECTION("a restart: the counter from 0 in warming_up after frames that were not") {
    acc.add(frame(40, 1000));
    acc.add(frame(41, 1000));
    CHECK(acc.close().starts == 0);
    acc.add(frame(0, 1000, warm));
    for (std::uint8_t s = 1; s < 100; ++s) acc.add(frame(s, 1000, warm));
    acc.add(frame(100, 1000));  // at specification: warming_up clear
    CHECK(acc.close().starts == 1);
    acc.add(frame(101, 1000));
    CHECK(acc.close().starts == 0);
  }
  SECTION("the first frame of a restart lost: the rising warming_up is still the start") {
    acc.add(frame(9, 1000));
    acc.add(frame(2, 1000, warm));  // 0 and 1 lost
    acc.add(frame(3, 1000, warm));
    CHECK(acc.close().starts == 1);
  }
  SECTION("a long warm-up wraps its counter without a new start, a restart within it is one") {
    acc.add(frame(0, 1000, warm));  // the first frame ever seen, at 0: the gyro's own first
    for (int s = 1; s < 300; ++s) acc.add(frame(static_cast<std::uint8_t>(s), 1000, warm));  // 255 -> 0
    CHECK(acc.close().starts == 1);
    acc.add(frame(0, 1000, warm));  // after 43 (299 mod 256): back to 0, a restart in the warm-up
    CHECK(acc.close().starts == 1);
  }
  SECTION("a gyro seen first in the middle of its warm-up: when it started is not told") {
    acc.add(frame(37, 1000, warm));
    acc.add(frame(38, 1000, warm));
    CHECK(acc.close().starts == 0);
  }
  SECTION("a repeated frame is no new start") {
    acc.add(frame(5, 1000));
    acc.add(frame(0, 1000, warm));
    acc.add(frame(0, 1000, warm));
    CHECK(acc.close().starts == 1);
  }
}

TEST_CASE("frames at the int32 count limit are counted saturated, others are not") {
  SampleAccumulator acc(rate_unit());
  constexpr std::int32_t hi = std::numeric_limits<std::int32_t>::max(), lo = std::numeric_limits<std::int32_t>::min();
  acc.add(frame(0, hi));
  acc.add(frame(1, hi - 1));  // one count short of the limit: a rate the scale still carries
  acc.add(frame(2, lo));
  acc.add(frame(3, hi, 0));   // not valid: not averaged, so not counted either
  GyroSample s = acc.close();
  CHECK(s.frames_used == 3);
  CHECK(s.frames_saturated == 2);
  // The next sample starts with none.
  acc.add(frame(4, 1000));
  s = acc.close();
  CHECK(s.frames_saturated == 0);
  CHECK(*s.rate_dph == Approx(1.0).epsilon(1e-12));
}
