// The gyro CAN frame codec: byte layout, CRC-8, and refusal of frames that are not gyro frames.
#include <catch2/catch.hpp>

#include <cstring>
#include <string_view>

#include "fogbench/drivers/can_frame.hpp"

using namespace fogbench::drivers;

TEST_CASE("crc8 is CRC-8/SAE-J1850 (check value of \"123456789\" is 0x4B)") {
  // The catalogued check value of CRC-8/SAE-J1850 (poly 0x1D, init 0xFF, xorout 0xFF).
  constexpr std::string_view check = "123456789";
  const auto* bytes = reinterpret_cast<const std::uint8_t*>(check.data());
  CHECK(can::crc8(std::span(bytes, check.size())) == 0x4B);
  // Empty input: the initial 0xFF XOR 0xFF.
  CHECK(can::crc8({}) == 0x00);
}

TEST_CASE("encode lays out a gyro frame byte for byte") {
  can::GyroFrame f{0x123, -2, 0xAB, can::status::valid | can::status::over_temperature};
  const can_frame cf = can::encode(f);
  CHECK(cf.can_id == 0x123u);
  CHECK(cf.can_dlc == 8);
  // -2 as little-endian two's complement int32: FE FF FF FF.
  CHECK(cf.data[0] == 0xFE);
  CHECK(cf.data[1] == 0xFF);
  CHECK(cf.data[2] == 0xFF);
  CHECK(cf.data[3] == 0xFF);
  CHECK(cf.data[4] == 0xAB);
  CHECK(cf.data[5] == 0x05);  // valid (bit 0) | over_temperature (bit 2)
  CHECK(cf.data[6] == 0x00);
  CHECK(cf.data[7] == can::crc8(std::span<const std::uint8_t>(cf.data, 7)));
}

TEST_CASE("encode then decode returns the frame, for extreme values") {
  for (std::int32_t counts : {0, 1, -1, 123456789, INT32_MIN, INT32_MAX}) {
    for (std::uint16_t id : {std::uint16_t{1}, std::uint16_t{0x101}, std::uint16_t{0x7FF}}) {
      can::GyroFrame f{id, counts, static_cast<std::uint8_t>(counts & 0xFF), 0x3F};
      auto d = can::decode(can::encode(f));
      REQUIRE(d.has_value());
      CHECK(d->node_id == id);
      CHECK(d->counts == counts);
      CHECK(d->sequence == f.sequence);
      CHECK(d->status == f.status);
    }
  }
}

TEST_CASE("every single flipped bit in bytes 0..7 is caught by the CRC") {
  // CRC-8 with a polynomial of more than one term detects every single-bit error.
  const can_frame good = can::encode({0x155, 987654, 17, can::status::valid});
  for (int byte = 0; byte < 8; ++byte) {
    for (int bit = 0; bit < 8; ++bit) {
      can_frame bad = good;
      bad.data[byte] = static_cast<std::uint8_t>(bad.data[byte] ^ (1u << bit));
      auto d = can::decode(bad);
      REQUIRE_FALSE(d.has_value());
      CHECK(d.error() == can::DecodeError::bad_crc);
    }
  }
}

TEST_CASE("a wrong DLC is refused even with a valid CRC over bytes 0..6") {
  can_frame f = can::encode({0x101, 5, 1, can::status::valid});
  for (std::uint8_t dlc : {std::uint8_t{0}, std::uint8_t{7}}) {
    f.can_dlc = dlc;
    auto d = can::decode(f);
    REQUIRE_FALSE(d.has_value());
    CHECK(d.error() == can::DecodeError::wrong_dlc);
  }
}

TEST_CASE("extended, remote and error frames are not gyro frames") {
  for (canid_t flag : {CAN_EFF_FLAG, CAN_RTR_FLAG, CAN_ERR_FLAG}) {
    can_frame f = can::encode({0x101, 5, 1, can::status::valid});
    f.can_id |= flag;
    auto d = can::decode(f);
    REQUIRE_FALSE(d.has_value());
    CHECK(d.error() == can::DecodeError::not_a_gyro_frame);
  }
}

TEST_CASE("status bits have names") {
  CHECK(can::status_to_string(0) == "none");
  CHECK(can::status_to_string(can::status::valid | can::status::light_source_fault) ==
        "valid|light_source_fault");
}
