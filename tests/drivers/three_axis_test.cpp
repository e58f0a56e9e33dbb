// Three-axis units (issue 29 point 3, drivers level): axis k of a unit sends on node_id + k, each
// axis has its own accumulator (sequence tracking, lost and corrupt counts) and its own sample,
// over the real unix transport; the configuration refuses overlapping ids and names unit and
// field; a one-axis configuration reads as before.
#include <catch2/catch.hpp>

#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <nlohmann/json.hpp>

#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "fogbench/drivers/can_frame.hpp"
#include "fogbench/drivers/config.hpp"
#include "fogbench/drivers/gyro_bus.hpp"

using namespace fogbench::drivers;
using nlohmann::json;
namespace fs = std::filesystem;

namespace {

constexpr std::uint8_t ok = can::status::valid;

struct TempDir {
  fs::path path;
  TempDir() {
    char tmpl[] = "/tmp/fogbench-three-axis-XXXXXX";
    REQUIRE(::mkdtemp(tmpl) != nullptr);
    path = tmpl;
  }
  ~TempDir() { fs::remove_all(path); }
};

struct Listener {
  int fd = -1;
  int peer = -1;
  explicit Listener(const fs::path& path) {
    fd = ::socket(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC, 0);
    REQUIRE(fd >= 0);
    sockaddr_un addr{};
    addr.sun_family = AF_UNIX;
    std::strncpy(addr.sun_path, path.c_str(), sizeof addr.sun_path - 1);
    REQUIRE(::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0);
    REQUIRE(::listen(fd, 1) == 0);
  }
  void accept_one() {
    peer = ::accept(fd, nullptr, nullptr);
    REQUIRE(peer >= 0);
  }
  void send_frame(const can_frame& f) const {
    REQUIRE(::send(peer, &f, sizeof f, 0) == static_cast<ssize_t>(sizeof f));
  }
  ~Listener() {
    if (peer >= 0) ::close(peer);
    ::close(fd);
  }
};

// A three-axis unit at 0x101 (ids 0x101..0x103) and a one-axis unit at 0x104.
std::vector<GyroChannelConfig> mixed_units() {
  GyroChannelConfig a;
  a.node_id = 0x101;
  a.axes = 3;
  a.scale_dph_per_count = 0.01;
  GyroChannelConfig b;
  b.node_id = 0x104;
  b.scale_dph_per_count = 0.5;
  return {a, b};
}

const fs::path map_dir = FOGBENCH_SOURCE_DIR "/drivers/maps";

json example() {
  std::ifstream in(FOGBENCH_SOURCE_DIR "/drivers/examples/mock-bench.json");
  REQUIRE(in);
  return json::parse(in);
}

std::string error_of(const json& j) {
  auto r = parse_drivers_config(j, map_dir);
  REQUIRE_FALSE(r.has_value());
  CHECK(r.error().code == ErrorCode::config);
  return r.error().message;
}

}  // namespace

TEST_CASE("a three-axis unit: each axis routed by node_id + axis to its own sample", "[three_axis]") {
  TempDir dir;
  const auto sock = dir.path / "can.sock";
  Listener bench(sock);
  auto bus = GyroBus::open({"unix:" + sock.string()}, mixed_units());
  REQUIRE(bus.has_value());
  bench.accept_one();
  CHECK(bus->unit_count() == 2);

  // Axis x (0x101): 100, 300 -> 2 deg/h. Axis y (0x102): -50 -> -0.5 deg/h. Axis z (0x103):
  // 1000 -> 10 deg/h. The one-axis unit (0x104): 6 -> 3 deg/h. The axes' counters all start at
  // 7 and each runs on its own: no axis's frame is a gap or a repeat of another's.
  bench.send_frame(can::encode({0x101, 100, 7, ok}));
  bench.send_frame(can::encode({0x102, -50, 7, ok}));
  bench.send_frame(can::encode({0x103, 1000, 7, ok}));
  bench.send_frame(can::encode({0x101, 300, 8, ok}));
  bench.send_frame(can::encode({0x104, 6, 7, ok}));
  bench.send_frame(can::encode({0x105, 1, 0, ok}));  // the id after the one-axis unit: no one's

  std::vector<can_frame> frames;
  auto n = bus->read_frames(frames);
  REQUIRE(n.has_value());
  CHECK(*n == 6);

  const BusSample s = bus->close_samples();
  REQUIRE(s.units.size() == 2);
  REQUIRE(s.extra_axes.size() == 2);
  // Axis 0 stays where a one-axis unit's sample is.
  CHECK(s.units[0].node_id == 0x101);
  CHECK(s.units[0].axis == 0);
  CHECK(s.units[0].frames == 2);
  CHECK(s.units[0].frames_lost == 0);
  CHECK(s.units[0].frames_repeated == 0);  // x's 7, 8 after y's and z's 7: no repeat, no gap
  REQUIRE(s.units[0].rate_dph.has_value());
  CHECK(*s.units[0].rate_dph == Approx(2.0));
  REQUIRE(s.extra_axes[0].size() == 2);
  const GyroSample& y = s.extra_axes[0][0];
  const GyroSample& z = s.extra_axes[0][1];
  CHECK(y.node_id == 0x101);
  CHECK(y.axis == 1);
  CHECK(y.frames == 1);
  CHECK(y.frames_repeated == 0);
  REQUIRE(y.rate_dph.has_value());
  CHECK(*y.rate_dph == Approx(-0.5));
  CHECK(z.axis == 2);
  CHECK(z.frames == 1);
  REQUIRE(z.rate_dph.has_value());
  CHECK(*z.rate_dph == Approx(10.0));
  // The one-axis unit: no extra axes, its sample as always.
  CHECK(s.extra_axes[1].empty());
  CHECK(s.units[1].node_id == 0x104);
  CHECK(s.units[1].axis == 0);
  REQUIRE(s.units[1].rate_dph.has_value());
  CHECK(*s.units[1].rate_dph == Approx(3.0));
  CHECK(s.frames_foreign == 1);
}

TEST_CASE("a three-axis unit: losses and corrupt frames are counted on the axis they happen on", "[three_axis]") {
  TempDir dir;
  const auto sock = dir.path / "can.sock";
  Listener bench(sock);
  auto bus = GyroBus::open({"unix:" + sock.string()}, mixed_units());
  REQUIRE(bus.has_value());
  bench.accept_one();

  // x: 0, 1, 2, 3 (none lost). y: 0, 3 (two lost). z: 0, a corrupt 1, 2 (one corrupt, none
  // lost: the corrupt frame explains the gap).
  for (std::uint8_t q = 0; q < 4; ++q) bench.send_frame(can::encode({0x101, 10, q, ok}));
  bench.send_frame(can::encode({0x102, 20, 0, ok}));
  bench.send_frame(can::encode({0x102, 20, 3, ok}));
  bench.send_frame(can::encode({0x103, 30, 0, ok}));
  can_frame bad = can::encode({0x103, 30, 1, ok});
  bad.data[2] ^= 0x10;
  bench.send_frame(bad);
  bench.send_frame(can::encode({0x103, 30, 2, ok}));

  std::vector<can_frame> frames;
  REQUIRE(bus->read_frames(frames).has_value());
  BusSample s = bus->close_samples();
  REQUIRE(s.extra_axes[0].size() == 2);
  CHECK(s.units[0].frames == 4);
  CHECK(s.units[0].frames_lost == 0);
  CHECK(s.units[0].frames_corrupt == 0);
  CHECK(s.extra_axes[0][0].frames == 2);
  CHECK(s.extra_axes[0][0].frames_lost == 2);
  CHECK(s.extra_axes[0][0].frames_corrupt == 0);
  CHECK(s.extra_axes[0][1].frames == 2);
  CHECK(s.extra_axes[0][1].frames_lost == 0);
  CHECK(s.extra_axes[0][1].frames_corrupt == 1);

  // Each axis's sequence tracking carries over the sample boundary on its own: y lost one
  // across it (3 -> 5), x none (3 -> 4).
  bench.send_frame(can::encode({0x101, 10, 4, ok}));
  bench.send_frame(can::encode({0x102, 20, 5, ok}));
  REQUIRE(bus->read_frames(frames).has_value());
  s = bus->close_samples();
  CHECK(s.units[0].frames_lost == 0);
  CHECK(s.extra_axes[0][0].frames_lost == 1);
  CHECK(s.extra_axes[0][1].frames == 0);
  CHECK_FALSE(s.extra_axes[0][1].rate_dph.has_value());
}

TEST_CASE("axes in the configuration: default 1, 3 accepted, ids overlapping another unit's named", "[three_axis]") {
  json j = example();
  // The example's units: 257 and 258.
  auto cfg = parse_drivers_config(j, map_dir);
  REQUIRE(cfg.has_value());
  CHECK(cfg->units[0].gyro.axes == 1);
  CHECK(cfg->units[1].gyro.axes == 1);

  j["units"][1]["gyro"]["node_id"] = 300;
  j["units"][1]["gyro"]["axes"] = 3;
  cfg = parse_drivers_config(j, map_dir);
  REQUIRE(cfg.has_value());
  CHECK(cfg->units[1].gyro.axes == 3);
  CHECK(cfg->units[1].gyro.axis_id(2) == 302);

  j["units"][1]["gyro"]["axes"] = 2;
  CHECK(error_of(j) == "units[1].gyro.axes: expected 1 or 3 (a gyro unit has one axis or three)");
  j["units"][1]["gyro"]["axes"] = 4;
  CHECK(error_of(j) == "units[1].gyro.axes: expected an integer 1..3 (got 4)");
  j["units"][1]["gyro"]["axes"] = "xyz";
  CHECK(error_of(j) == "units[1].gyro.axes: expected an integer 1..3 (got a string)");

  // Unit 0 three-axis at 257 takes 257..259: unit 1 at 258 is on its axis 1.
  j = example();
  j["units"][0]["gyro"]["axes"] = 3;
  CHECK(error_of(j) ==
        "units[1].gyro.node_id: 258: the id 258 of its axis 0 is already the id of units[0]'s axis 1 "
        "(a three-axis unit sends on node_id, node_id + 1 and node_id + 2)");
  // Unit 1 three-axis at 256 would take 256..258: its axis 1 is unit 0's id.
  j = example();
  j["units"][1]["gyro"]["node_id"] = 256;
  j["units"][1]["gyro"]["axes"] = 3;
  CHECK(error_of(j) ==
        "units[1].gyro.node_id: 256: the id 257 of its axis 1 is already the id of units[0]'s axis 0 "
        "(a three-axis unit sends on node_id, node_id + 1 and node_id + 2)");
  // The last axis past the standard ids.
  j = example();
  j["units"][1]["gyro"]["node_id"] = 2046;
  j["units"][1]["gyro"]["axes"] = 3;
  CHECK(error_of(j) ==
        "units[1].gyro.node_id: 2046 with 3 axes needs ids up to 2048 (axis k sends on node_id + k; "
        "standard ids end at 2047)");
}

TEST_CASE("a three-axis unit is refused on a serial line, naming the field", "[three_axis]") {
  const fs::path examples = FOGBENCH_SOURCE_DIR "/drivers/examples";
  json j = example();
  j["units"].erase(1);
  j["gyro_bus"] = {{"transport", "serial:/dev/ttyUSB0?baud=921600"}, {"frame", (examples / "kvh-1775-format-a.json").string()}};
  REQUIRE(parse_drivers_config(j, map_dir).has_value());
  j["units"][0]["gyro"]["axes"] = 3;
  CHECK(error_of(j) == "units[0].gyro.axes: a serial gyro's frame carries one axis: expected 1 (three-axis units are read on CAN)");

  j = example();
  j["units"][1]["gyro"] = {{"node_id", 258}, {"axes", 3}, {"scale_dph_per_count", 1e-4}};
  j["units"][1]["gyro"]["node_id"] = 300;
  j["units"][1]["gyro_line"] = {{"transport", "serial:/dev/ttyUSB1?baud=921600"},
                                {"frame", (examples / "kvh-1775-format-a.json").string()}};
  CHECK(error_of(j) == "units[1].gyro.axes: a serial gyro's frame carries one axis: expected 1 (three-axis units are read on CAN)");
}

TEST_CASE("one-axis units: the bus sample is as before, no extra axes", "[three_axis]") {
  GyroChannelConfig a;
  a.node_id = 0x101;
  a.scale_dph_per_count = 0.01;
  GyroChannelConfig b = a;
  b.node_id = 0x102;
  const auto empty = fs::temp_directory_path() / "fogbench-three-axis-empty.log";
  { std::ofstream(empty.string()).flush(); }
  auto bus = GyroBus::open({"replay:" + empty.string() + "?speed=0"}, {a, b});
  REQUIRE(bus.has_value());
  bus->route(can::encode({0x101, 100, 0, ok}));
  bus->route(can::encode({0x102, 200, 0, ok}));
  bus->route(can::encode({0x103, 300, 0, ok}));  // node_id + 1 of a one-axis unit: foreign
  const BusSample s = bus->close_samples();
  REQUIRE(s.units.size() == 2);
  CHECK(*s.units[0].rate_dph == Approx(1.0));
  CHECK(*s.units[1].rate_dph == Approx(2.0));
  CHECK(s.units[1].node_id == 0x102);
  REQUIRE(s.extra_axes.size() == 2);
  CHECK(s.extra_axes[0].empty());
  CHECK(s.extra_axes[1].empty());
  CHECK(s.frames_foreign == 1);
  fs::remove(empty);
}

namespace {

// An int16 centi-degC channel at input `address`, as the example's unit 0 has.
json axis_channel(int address) {
  return {{"function", "input"}, {"address", address}, {"type", "int16"}, {"scale", 0.01},
          {"kind", "temperature"}, {"open_circuit_raw", 32767}};
}

// The example with unit 0 a three-axis unit whose axes have thermistors of their own.
json per_axis_example() {
  json j = example();
  j["units"][0]["gyro"]["node_id"] = 300;
  j["units"][0]["gyro"]["axes"] = 3;
  j["units"][0]["thermistors"] = {{"x", {{"t1", axis_channel(0)}, {"t2", axis_channel(1)}}},
                                  {"y", {{"t1", axis_channel(10)}, {"t2", axis_channel(11)}}},
                                  {"z", {{"t1", axis_channel(12)}, {"t2", axis_channel(13)}}}};
  return j;
}

}  // namespace

TEST_CASE("thermistors per axis in the configuration: x, y and z each a channel per sensor", "[three_axis][axis_thermistors]") {
  auto cfg = parse_drivers_config(per_axis_example(), map_dir);
  REQUIRE(cfg.has_value());
  const UnitConfig& u = cfg->units[0];
  REQUIRE(u.has_axis_thermistors());
  // x's are the unit's t1, t2; y's and z's in axis_thermistors.
  CHECK(u.t1.reg.address == 0);
  CHECK(u.t2.reg.address == 1);
  CHECK(u.axis_thermistors[0][0].reg.address == 10);
  CHECK(u.axis_thermistors[0][1].reg.address == 11);
  CHECK(u.axis_thermistors[1][0].reg.address == 12);
  CHECK(u.axis_thermistors[1][1].reg.address == 13);
  CHECK_FALSE(cfg->units[1].has_axis_thermistors());  // the shared form reads as before
}

TEST_CASE("thermistors per axis: a missing axis, a mix with t1 and t2, a one-axis gyro, an overlap are named", "[three_axis][axis_thermistors]") {
  json j = per_axis_example();
  j["units"][0]["thermistors"].erase("z");
  CHECK_THAT(error_of(j), Catch::StartsWith("units[0].thermistors.z: missing: a three-axis unit's thermistors per axis name every axis"));
  j = per_axis_example();
  j["units"][0]["thermistors"]["y"].erase("t2");
  CHECK(error_of(j) == "units[0].thermistors.y.t2: missing (expected an object)");
  j = per_axis_example();
  j["units"][0]["thermistors"]["t1"] = axis_channel(20);
  CHECK_THAT(error_of(j), Catch::StartsWith("units[0].thermistors.t1: beside per-axis thermistors (x, y, z)"));
  j = per_axis_example();
  j["units"][0]["gyro"]["axes"] = 1;
  CHECK(error_of(j) == "units[0].thermistors: per-axis thermistors (x, y, z) need a three-axis gyro (gyro.axes 3); this unit's has 1");
  j = per_axis_example();
  j["units"][0]["thermistors"]["z"]["t2"] = axis_channel(10);  // on y's T1
  CHECK(error_of(j) == "units[0].thermistors.z.t2.address: input 10 (int16) overlaps units[0].thermistors.y.t1 (input 10 (int16))");
}
