// The mock bench's serial gyro peer read by the drivers' serial transport through its pty link:
// the same rates, gaps and corrupt frames as the CAN frames it is fed.
#include <catch2/catch.hpp>

#include <poll.h>
#include <stdlib.h>
#include <unistd.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <filesystem>
#include <fstream>

#include "fogbench/drivers/can_frame.hpp"
#include "fogbench/drivers/gyro_bus.hpp"
#include "faults.hpp"
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

TEST_CASE("a UART at another baud rate mis-samples the sent waveform: exact for simple bytes", "[serial]") {
  const std::vector<std::uint8_t> frame = {0xFE, 0x81, 0xFF, 0x55, 0x00, 0x12, 0xA7};
  CHECK(mock::uart_resample(frame, 921600, 921600) == frame);  // the same rate: the same bytes
  // Read at twice the rate: 0xFF is a start bit 0 and ones; the receiver's bit 0 falls in the
  // start bit, bits 1..7 in the ones: 0xFE, and nothing more (the line stays high).
  const std::vector<std::uint8_t> ff = {0xFF};
  CHECK(mock::uart_resample(ff, 9600, 19200) == std::vector<std::uint8_t>{0xFE});
  // Read at half the rate: 0x00's receiver bits sample sent slots 3, 5, 7 (zeros), 9 (stop: 1),
  // 11.. (idle: 1): 0xF8.
  const std::vector<std::uint8_t> zero = {0x00};
  CHECK(mock::uart_resample(zero, 19200, 9600) == std::vector<std::uint8_t>{0xF8});
  // 8x slower sender: more bytes than were sent, none of them the frame.
  const auto slow = mock::uart_resample(frame, 115200, 921600);
  CHECK(slow.size() > frame.size());
  CHECK(slow != frame);
  CHECK(mock::uart_resample({}, 9600, 19200).empty());
}

TEST_CASE("serial line faults from the fault commands: garbage, cut, bad CRC and a wrong baud rate counted, good frames after", "[serial][faults]") {
  char tmpl[] = "/tmp/fogbench-serial-faults-XXXXXX";
  REQUIRE(::mkdtemp(tmpl) != nullptr);
  const std::filesystem::path dir = tmpl;
  std::ifstream in(FOGBENCH_SOURCE_DIR "/drivers/examples/kvh-1775-format-a.json");
  auto format = drivers::serial::parse_frame_format(json::parse(in), "frame");
  REQUIRE(format.has_value());
  mock::SerialGyroPeer peer;
  const auto link = (dir / "gyro").string();
  REQUIRE(peer.open(link, *format, 0x101, 1e-3).has_value());

  drivers::GyroBusConfig cfg;
  cfg.transport = "serial:" + link + "?baud=921600";
  cfg.frame = *format;
  drivers::GyroChannelConfig unit;
  unit.node_id = 0x101;
  unit.scale_dph_per_count = 1e-3;
  unit.startup_flag = false;
  auto bus = drivers::GyroBus::open(cfg, {unit});
  REQUIRE(bus.has_value());

  // The same path as the bench's control socket: a JSON command, parsed and applied to the
  // bench's fault state, whose serial part the peer takes.
  mock::FaultState state;
  state.units.resize(1);
  const auto fault = [&](const json& j) {
    auto c = mock::parse_fault_command(j, {"SIM-0001"});
    INFO(j.dump());
    REQUIRE(c.has_value());
    mock::apply_fault(state, *c, 0.0);
    peer.set_faults(state.serial);
  };
  std::uint8_t seq = 0;
  const auto send = [&](int n) {
    std::vector<::can_frame> frames;
    for (int i = 0; i < n; ++i) frames.push_back(drivers::can::encode({0x101, 7000, seq++, drivers::can::status::valid}));
    peer.send(frames);
  };
  // Reads until `want` CAN frames came (good and corrupt) or, with want 0, until `until` is in
  // an event; a 2 s quiet line ends it (a failure, not a timing assertion).
  std::vector<std::string> events;
  const auto read = [&](std::size_t want, const std::string& until = {}) {
    std::vector<::can_frame> batch;
    std::size_t got = 0;
    for (;;) {
      if (want > 0 && got >= want) break;
      if (want == 0 && std::any_of(events.begin(), events.end(), [&](const std::string& e) { return e.find(until) != std::string::npos; })) break;
      pollfd p{bus->fd(), POLLIN, 0};
      if (::poll(&p, 1, 2000) <= 0) break;
      REQUIRE(bus->read_frames(batch).has_value());
      got += batch.size();
      for (auto& e : bus->take_events()) events.push_back(e.message);
    }
    return got;
  };
  const auto count = [&](const std::string& what) {
    return std::count_if(events.begin(), events.end(), [&](const std::string& e) { return e.find(what) != std::string::npos; });
  };

  SECTION("garbage before every other frame: one malformed run each, no frame lost") {
    fault({{"name", "serial_garbage"}, {"fraction", 0.5}, {"bytes", 7}});
    send(10);
    CHECK(read(10) == 10);
    const auto s = bus->close_samples();
    CHECK(s.units[0].frames == 10);
    CHECK(s.units[0].frames_lost == 0);
    CHECK(s.units[0].frames_corrupt == 0);
    CHECK(s.malformed_total == 5);
    CHECK(count(": 7 bytes between frames skipped") == 5);
  }
  SECTION("every 4th frame cut in half: corrupt, not lost") {
    fault({{"name", "serial_cut"}, {"fraction", 0.25}});
    send(10);  // frames 4 and 8 cut; the 10th whole, so no cut frame waits at the end
    CHECK(read(10) == 10);
    const auto s = bus->close_samples();
    CHECK(s.units[0].frames == 8);
    CHECK(s.units[0].frames_corrupt == 2);
    CHECK(s.units[0].frames_lost == 0);
    CHECK(count("frame cut short, the next sync word began 18 bytes into it") == 2);
  }
  SECTION("every 5th frame with a bad CRC: corrupt, not lost") {
    fault({{"name", "serial_bad_crc"}, {"fraction", 0.2}});
    send(10);
    CHECK(read(10) == 10);
    const auto s = bus->close_samples();
    CHECK(s.units[0].frames == 8);
    CHECK(s.units[0].frames_corrupt == 2);
    CHECK(s.units[0].frames_lost == 0);
    CHECK(count("bad_crc at byte") == 2);
  }
  SECTION("the gyro at 115200 baud on a 921600 line: no frame, no_frame naming the line, then good frames again") {
    send(3);
    CHECK(read(3) == 3);
    (void)bus->close_samples();
    fault({{"name", "serial_baud"}, {"baud", 115200}, {"line_baud", 921600}});
    send(20);
    CHECK(read(0, "no_frame") == 0);
    REQUIRE(count("no_frame") == 1);
    const auto line = *std::find_if(events.begin(), events.end(), [](const std::string& e) { return e.find("no_frame") != std::string::npos; });
    INFO(line);
    CHECK(line.find("0 sync words seen") != std::string::npos);
    CHECK(line.find("a wrong baud rate or framing") != std::string::npos);
    CHECK(line.find("; configured 921600 baud 8N1") != std::string::npos);
    CHECK(bus->close_samples().units[0].frames == 0);

    fault({{"name", "serial_baud"}, {"on", false}});
    send(10);
    CHECK(read(10) == 10);
    const auto s = bus->close_samples();
    CHECK(s.units[0].frames == 10);
    CHECK(s.units[0].frames_lost == 20);  // the 20 frames sent at the wrong rate
    CHECK(s.units[0].frames_corrupt == 0);
    REQUIRE(s.units[0].rate_dph.has_value());
    CHECK(*s.units[0].rate_dph == Approx(7.0));
  }
  SECTION("the faults off: every frame good again") {
    fault({{"name", "serial_bad_crc"}, {"fraction", 1}});
    fault({{"name", "serial_bad_crc"}, {"on", false}});
    send(5);
    CHECK(read(5) == 5);
    CHECK(bus->close_samples().units[0].frames == 5);
    CHECK(events.empty());
  }
  peer.close();
  std::filesystem::remove_all(dir);
}

TEST_CASE("serial fault commands: parameters checked by name, listed while active", "[serial][faults]") {
  const std::vector<std::string> serials = {"SIM-0001"};
  CHECK(mock::parse_fault_command({{"name", "serial_garbage"}, {"fraction", 2}}, serials).error() ==
        "serial_garbage: fraction: expected 0..1 (got 2)");
  CHECK(mock::parse_fault_command({{"name", "serial_garbage"}, {"fraction", 0.5}, {"bytes", 2.5}}, serials).error() ==
        "serial_garbage: bytes: expected a whole number");
  CHECK(mock::parse_fault_command({{"name", "serial_baud"}}, serials).error() == "serial_baud: baud: missing");
  CHECK(mock::parse_fault_command({{"name", "serial_baud"}, {"baud", 9600}, {"unit", 0}}, serials).error() ==
        "serial_baud.unit: unknown field (known: baud, line_baud, on)");
  CHECK(mock::parse_fault_command({{"name", "serial_baud"}, {"baud", 9600.5}}, serials).error() ==
        "serial_baud: baud: expected a whole number of bits/s");
  mock::FaultState state;
  state.units.resize(1);
  for (const json& j : {json{{"name", "serial_garbage"}, {"fraction", 0.1}}, json{{"name", "serial_cut"}, {"fraction", 0.01}},
                        json{{"name", "serial_bad_crc"}, {"fraction", 0.02}}, json{{"name", "serial_baud"}, {"baud", 460800}}}) {
    auto c = mock::parse_fault_command(j, serials);
    REQUIRE(c.has_value());
    mock::apply_fault(state, *c, 0.0);
  }
  CHECK(state.serial.garbage_bytes == 5);
  CHECK(state.serial.line_baud == 921600);
  const auto active = mock::active_faults(state, serials, 0.0);
  REQUIRE(active.size() == 4);
  CHECK(active[3] == json{{"name", "serial_baud"}, {"baud", 460800}, {"line_baud", 921600}});
  auto cli = mock::fault_json_from_cli("serial_baud=115200,line_baud=921600");
  REQUIRE(cli.has_value());
  CHECK((*cli)["baud"] == 115200);
  CHECK((*cli)["line_baud"] == 921600);
}
