// fogbench-sim --serial-gyro: the first unit's frames read by the drivers' serial transport
// through the pty link the process makes, none lost or corrupt once the reader is up.
#include <catch2/catch.hpp>

#include <poll.h>
#include <stdlib.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "fogbench/drivers/gyro_bus.hpp"
#include "mock_process.hpp"

using namespace fogbench;
using mockbench::MockProcess;
using nlohmann::json;

TEST_CASE("fogbench-sim serves a serial gyro on a pty the serial transport reads without loss", "[serial]") {
  char tmpl[] = "/tmp/fogbench-serial-sim-XXXXXX";
  REQUIRE(::mkdtemp(tmpl) != nullptr);
  const std::filesystem::path dir = tmpl;
  const auto link = (dir / "gyro").string();
  const std::string frame_file = FOGBENCH_SOURCE_DIR "/drivers/examples/kvh-1775-format-a.json";
  {
    MockProcess sim({"--units", "1", "--time-scale", "10", "--frame-rate-hz", "100", "--serial-gyro", link,
                     "--serial-frame", frame_file});
    REQUIRE(sim.ready()["serial_gyro"] == link);
    const auto& gyro_json = sim.ready()["drivers_config"]["units"][0]["gyro"];
    drivers::GyroChannelConfig unit;
    unit.node_id = gyro_json["node_id"].get<std::uint16_t>();
    unit.scale_dph_per_count = gyro_json["scale_dph_per_count"].get<double>();
    unit.startup_flag = false;
    std::ifstream in(frame_file);
    auto format = drivers::serial::parse_frame_format(json::parse(in), "frame");
    REQUIRE(format.has_value());
    drivers::GyroBusConfig cfg;
    cfg.transport = "serial:" + link;
    cfg.frame = *format;
    auto bus = drivers::GyroBus::open(cfg, {unit});
    REQUIRE(bus.has_value());

    const auto read = [&](std::size_t want) {
      std::vector<::can_frame> batch;
      std::size_t got = 0;
      while (got < want) {
        pollfd p{bus->fd(), POLLIN, 0};
        if (::poll(&p, 1, 10000) <= 0) break;
        auto n = bus->read_frames(batch);
        REQUIRE(n.has_value());
        got += *n;
      }
      return got;
    };
    // What the pty held before the reader came may begin with a frame cut where its buffer was
    // full: that first part is read and set aside.
    REQUIRE(read(50) >= 50);
    bus->close_samples();
    (void)bus->take_events();
    REQUIRE(read(300) >= 300);
    const auto s = bus->close_samples();
    INFO("fogbench-sim stderr:\n" << sim.log());
    CHECK(s.units[0].frames >= 300);
    CHECK(s.units[0].frames_lost == 0);
    CHECK(s.units[0].frames_corrupt == 0);
    REQUIRE(s.units[0].rate_dph.has_value());
    CHECK(std::isfinite(*s.units[0].rate_dph));
    CHECK(bus->take_events().empty());
  }
  CHECK_FALSE(std::filesystem::exists(link));  // removed when the bench stops
  std::filesystem::remove_all(dir);
}
