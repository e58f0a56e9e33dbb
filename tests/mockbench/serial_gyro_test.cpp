// The mock bench's serial gyro peer read by the drivers' serial transport through its pty link:
// the same rates, gaps and corrupt frames as the CAN frames it is fed.
#include <catch2/catch.hpp>

#include <poll.h>
#include <stdlib.h>
#include <unistd.h>

#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>

#include "fogbench/drivers/can_frame.hpp"
#include "fogbench/drivers/gyro_bus.hpp"
#include "serial_gyro.hpp"

using namespace fogbench;
using nlohmann::json;

TEST_CASE("the mock serial gyro serves a unit's CAN frames as KVH frames the serial transport reads", "[serial]") {
  char tmpl[] = "/tmp/fogbench-serial-peer-XXXXXX";
  REQUIRE(::mkdtemp(tmpl) != nullptr);
  const std::filesystem::path dir = tmpl;
  std::ifstream in(FOGBENCH_SOURCE_DIR "/drivers/examples/kvh-1775-format-a.json");
  auto format = drivers::serial::parse_frame_format(json::parse(in), "frame");
  REQUIRE(format.has_value());

  mock::SerialGyroPeer peer;
  const auto link = (dir / "gyro").string();
  REQUIRE(peer.open(link, *format, 0x101, 1e-3).has_value());
  CHECK(std::filesystem::is_symlink(link));

  drivers::GyroBusConfig cfg;
  cfg.transport = "serial:" + link + "?baud=921600";
  cfg.frame = *format;
  drivers::GyroChannelConfig unit;
  unit.node_id = 0x101;
  unit.scale_dph_per_count = 1e-3;
  unit.startup_flag = false;
  auto bus = drivers::GyroBus::open(cfg, {unit});
  REQUIRE(bus.has_value());

  std::vector<::can_frame> frames;
  for (int seq : {254, 255, 1, 2, 3}) {  // 0 lost; the wrap carried onto the 7-bit counter
    frames.push_back(drivers::can::encode({0x101, 5000, static_cast<std::uint8_t>(seq), drivers::can::status::valid}));
  }
  frames[3].data[0] ^= 0x04;  // seq 2 corrupt on CAN: its serial frame's CRC is broken
  frames.push_back(drivers::can::encode({0x102, 1, 4, drivers::can::status::valid}));  // another unit: not served
  peer.send(frames);

  std::vector<::can_frame> got, batch;
  while (got.size() < 5) {
    pollfd p{bus->fd(), POLLIN, 0};
    if (::poll(&p, 1, 2000) <= 0) break;
    REQUIRE(bus->read_frames(batch).has_value());
    got.insert(got.end(), batch.begin(), batch.end());
  }
  CHECK(got.size() == 5);
  const auto s = bus->close_samples();
  CHECK(s.units[0].frames == 4);
  CHECK(s.units[0].frames_corrupt == 1);
  CHECK(s.units[0].frames_lost == 1);
  REQUIRE(s.units[0].rate_dph.has_value());
  CHECK(*s.units[0].rate_dph == Approx(5.0));
  const auto events = bus->take_events();
  REQUIRE(events.size() == 1);
  CHECK(events[0].message.find("bad_crc") != std::string::npos);

  peer.close();
  CHECK_FALSE(std::filesystem::exists(link));
  std::filesystem::remove_all(dir);
}
