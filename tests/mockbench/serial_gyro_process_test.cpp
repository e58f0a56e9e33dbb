// fogbench-sim --serial-gyro: the first unit's frames read by the drivers' serial transport
// through the pty link the process makes, none lost or corrupt once the reader is up.
#include <catch2/catch.hpp>

#include <poll.h>
#include <stdlib.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "fogbench/drivers/config.hpp"
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

TEST_CASE("fogbench-sim's drivers_config with --serial-gyro: the first unit on its serial line, the second on CAN, one bus", "[serial]") {
  char tmpl[] = "/tmp/fogbench-serial-mixed-XXXXXX";
  REQUIRE(::mkdtemp(tmpl) != nullptr);
  const std::filesystem::path dir = tmpl;
  const auto link = (dir / "gyro").string();
  {
    MockProcess sim({"--units", "2", "--time-scale", "10", "--frame-rate-hz", "100", "--serial-gyro", link,
                     "--serial-frame", FOGBENCH_SOURCE_DIR "/drivers/examples/kvh-1775-format-a.json"});
    const auto& served = sim.ready()["drivers_config"];
    CHECK(served["units"][0]["gyro_line"]["transport"] == "serial:" + link + "?baud=921600");
    CHECK(served["units"][0]["gyro"]["startup_flag"] == false);
    CHECK_FALSE(served["units"][1].contains("gyro_line"));
    auto cfg = drivers::parse_drivers_config(served, FOGBENCH_SOURCE_DIR "/drivers/maps");
    INFO((cfg ? std::string() : cfg.error().message));
    REQUIRE(cfg.has_value());
    REQUIRE(cfg->gyro_bus.lines.size() == 1);
    std::vector<drivers::GyroChannelConfig> channels;
    for (const auto& u : cfg->units) channels.push_back(u.gyro);
    auto bus = drivers::GyroBus::open(cfg->gyro_bus, channels);
    INFO((bus ? std::string() : bus.error().message));
    REQUIRE(bus.has_value());
    CHECK(bus->transport().describe().find(" + serial:" + link) != std::string::npos);

    // Until both units have 200 frames (a 10 s guard: the bench sends 1,000 a second of each).
    const auto read_until = [&](std::uint32_t want) {
      std::uint32_t got[2] = {0, 0};
      std::vector<::can_frame> batch;
      while (got[0] < want || got[1] < want) {
        pollfd p{bus->fd(), POLLIN, 0};
        if (::poll(&p, 1, 10000) <= 0) break;
        auto n = bus->read_frames(batch);
        REQUIRE(n.has_value());
        for (const auto& f : batch) {
          if ((f.can_id & CAN_SFF_MASK) == channels[0].node_id) ++got[0];
          if ((f.can_id & CAN_SFF_MASK) == channels[1].node_id) ++got[1];
        }
      }
    };
    // What the pty held before the reader came may begin with a cut frame: set aside.
    read_until(50);
    (void)bus->close_samples();
    (void)bus->take_events();
    read_until(200);
    const auto s = bus->close_samples();
    INFO("fogbench-sim stderr:\n" << sim.log());
    REQUIRE(s.units.size() == 2);
    for (std::size_t u = 0; u < 2; ++u) {
      INFO("unit " << u);
      CHECK(s.units[u].frames >= 200);
      CHECK(s.units[u].frames_lost == 0);
      CHECK(s.units[u].frames_corrupt == 0);
    }
    REQUIRE(s.units[0].rate_dph.has_value());
    CHECK(std::isfinite(*s.units[0].rate_dph));
    CHECK(s.frames_foreign == 0);
    CHECK(bus->take_events().empty());
  }
  std::filesystem::remove_all(dir);
}
