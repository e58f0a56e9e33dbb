// The gyro bus end to end: the AF_UNIX SOCK_SEQPACKET transport against a listening socket made
// here, candump log replay (unpaced and paced by an injected clock), transport strings, and
// the candump line format.
#include <catch2/catch.hpp>

#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "fogbench/drivers/can_frame.hpp"
#include "fogbench/drivers/candump.hpp"
#include "fogbench/drivers/gyro_bus.hpp"

using namespace fogbench::drivers;
namespace fs = std::filesystem;

namespace {

// A private directory for sockets and logs, removed at the end of the test.
struct TempDir {
  fs::path path;
  TempDir() {
    char tmpl[] = "/tmp/fogbench-drivers-XXXXXX";
    REQUIRE(::mkdtemp(tmpl) != nullptr);
    path = tmpl;
  }
  ~TempDir() { fs::remove_all(path); }
};

// The mock bench's side: listen on a SEQPACKET socket, accept one client.
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

std::vector<GyroChannelConfig> two_units() {
  GyroChannelConfig a;
  a.node_id = 0x101;
  a.scale_dph_per_count = 0.01;
  GyroChannelConfig b;
  b.node_id = 0x102;
  b.scale_dph_per_count = 0.5;
  return {a, b};
}

constexpr std::uint8_t ok = can::status::valid;

}  // namespace

TEST_CASE("unix SOCK_SEQPACKET transport: frames sent by the bench arrive decoded and routed") {
  TempDir dir;
  const auto sock = dir.path / "can.sock";
  Listener bench(sock);
  auto bus = GyroBus::open({"unix:" + sock.string()}, two_units());
  REQUIRE(bus.has_value());
  bench.accept_one();
  CHECK(bus->fd() >= 0);

  // Unit 0x101: counts 100, 300 (mean 200 * 0.01 = 2 deg/h), sequence 5 -> 7 loses one.
  bench.send_frame(can::encode({0x101, 100, 5, ok}));
  bench.send_frame(can::encode({0x101, 300, 7, ok}));
  // Unit 0x102: counts -4 (-4 * 0.5 = -2 deg/h), and a corrupted copy.
  bench.send_frame(can::encode({0x102, -4, 0, ok}));
  can_frame bad = can::encode({0x102, -4, 1, ok});
  bad.data[0] ^= 0x01;
  bench.send_frame(bad);
  // An id of no unit, and a datagram that is not a frame (10 bytes).
  bench.send_frame(can::encode({0x200, 1, 0, ok}));
  const char junk[10] = {};
  REQUIRE(::send(bench.peer, junk, sizeof junk, 0) == 10);

  // Unix datagrams are queued by the time send() returns: one non-blocking read gets them all.
  std::vector<can_frame> frames;
  auto n = bus->read_frames(frames);
  REQUIRE(n.has_value());
  CHECK(*n == 5);
  CHECK(frames.size() == 5);
  CHECK(frames[0].can_id == 0x101u);

  // Nothing more: a non-blocking read returns 0, not an error.
  auto again = bus->read_frames(frames);
  REQUIRE(again.has_value());
  CHECK(*again == 0);

  const BusSample s = bus->close_samples();
  REQUIRE(s.units.size() == 2);
  CHECK(s.units[0].frames == 2);
  CHECK(s.units[0].frames_lost == 1);
  REQUIRE(s.units[0].rate_dph.has_value());
  CHECK(*s.units[0].rate_dph == Approx(2.0));
  CHECK(s.units[1].frames == 1);
  CHECK(s.units[1].frames_corrupt == 1);
  CHECK(*s.units[1].rate_dph == Approx(-2.0));
  CHECK(s.frames_foreign == 1);
  CHECK(s.malformed_total == 1);

  // The bench goes away: a connection error value, and reopen() fails while nobody listens.
  ::close(bench.peer);
  bench.peer = -1;
  auto closed = bus->read_frames(frames);
  REQUIRE_FALSE(closed.has_value());
  CHECK(closed.error().code == ErrorCode::connection);
}

TEST_CASE("unix transport: connecting where no bench listens is a connection error") {
  TempDir dir;
  auto bus = GyroBus::open({"unix:" + (dir.path / "nobody.sock").string()}, two_units());
  REQUIRE_FALSE(bus.has_value());
  CHECK(bus.error().code == ErrorCode::connection);
}

TEST_CASE("unix transport: a large burst arrives without loss") {
  TempDir dir;
  const auto sock = dir.path / "can.sock";
  Listener bench(sock);
  auto bus = GyroBus::open({"unix:" + sock.string()}, two_units());
  REQUIRE(bus.has_value());
  bench.accept_one();
  // 2000 frames in bursts of 100 (a burst fits the socket buffer), read after each burst.
  std::vector<can_frame> frames;
  std::size_t received = 0;
  for (int burst = 0; burst < 20; ++burst) {
    for (int i = 0; i < 100; ++i) {
      const int k = burst * 100 + i;
      bench.send_frame(can::encode({0x101, k, static_cast<std::uint8_t>(k), ok}));
    }
    auto n = bus->read_frames(frames);
    REQUIRE(n.has_value());
    received += *n;
  }
  CHECK(received == 2000);
  const BusSample s = bus->close_samples();
  CHECK(s.units[0].frames == 2000);
  CHECK(s.units[0].frames_lost == 0);
  // Mean of 0..1999 = 999.5 counts * 0.01 = 9.995 deg/h.
  CHECK(*s.units[0].rate_dph == Approx(9.995));
}

namespace {

// A log of unit 0x101 at 0.0, 0.5 and 1.0 s, with a foreign frame and a line that is no frame.
fs::path write_log(const fs::path& dir) {
  const auto file = dir / "bench.log";
  std::ofstream out(file);
  const std::int64_t t0 = 1700000000'000000;
  out << format_candump_line(t0, "can0", can::encode({0x101, 10, 0, ok})) << "\n";
  out << format_candump_line(t0 + 250000, "can0", can::encode({0x300, 1, 0, ok})) << "\n";
  out << "this line is not a frame\n";
  out << format_candump_line(t0 + 500000, "can0", can::encode({0x101, 20, 1, ok})) << "\n";
  out << format_candump_line(t0 + 1000000, "can0", can::encode({0x101, 30, 2, ok})) << "\n";
  return file;
}

}  // namespace

TEST_CASE("replay of a candump log, as fast as read") {
  TempDir dir;
  const auto log = write_log(dir.path);
  auto bus = GyroBus::open({"replay:" + log.string() + "?speed=0"}, two_units());
  REQUIRE(bus.has_value());
  std::vector<can_frame> frames;
  auto n = bus->read_frames(frames);
  REQUIRE(n.has_value());
  CHECK(*n == 4);
  auto end = bus->read_frames(frames);
  REQUIRE_FALSE(end.has_value());
  CHECK(end.error().code == ErrorCode::end_of_stream);
  const BusSample s = bus->close_samples();
  CHECK(s.units[0].frames == 3);
  CHECK(*s.units[0].rate_dph == Approx(0.2));  // mean 20 counts * 0.01
  CHECK(s.frames_foreign == 1);
  CHECK(s.malformed_total == 1);
}

TEST_CASE("replay is paced by the log's timestamps (injected clock)") {
  TempDir dir;
  const auto log = write_log(dir.path);
  std::chrono::nanoseconds now{1'000'000'000};
  auto clock = [&now] { return now; };
  using namespace std::chrono_literals;

  // Speed 2: the log's 0.5 s and 1.0 s frames are due after 0.25 s and 0.5 s.
  auto bus = GyroBus::open({"replay:" + log.string() + "?speed=2"}, two_units(), clock);
  REQUIRE(bus.has_value());
  std::vector<can_frame> frames;
  CHECK(*bus->read_frames(frames) == 1);  // the first frame is due at once
  now += 100ms;                            // log time 0.2 s: the foreign frame (0.25 s) not yet
  CHECK(*bus->read_frames(frames) == 0);
  now += 100ms;                            // log time 0.4 s: the foreign frame
  CHECK(*bus->read_frames(frames) == 1);
  CHECK(frames[0].can_id == 0x300u);
  now += 50ms;                             // log time 0.5 s: the second frame of 0x101
  CHECK(*bus->read_frames(frames) == 1);
  now += 249ms;                            // log time 0.998 s
  CHECK(*bus->read_frames(frames) == 0);
  now += 1ms;                              // log time 1.0 s
  CHECK(*bus->read_frames(frames) == 1);
  CHECK(bus->read_frames(frames).error().code == ErrorCode::end_of_stream);
}

TEST_CASE("transport strings") {
  auto can = parse_transport_spec("can:can0");
  REQUIRE(can.has_value());
  CHECK(can->kind == TransportSpec::Kind::socketcan);
  CHECK(can->target == "can0");
  auto unix_spec = parse_transport_spec("unix:/run/fogbench/can.sock");
  REQUIRE(unix_spec.has_value());
  CHECK(unix_spec->kind == TransportSpec::Kind::unix_seqpacket);
  auto replay = parse_transport_spec("replay:runs/a.log?speed=10");
  REQUIRE(replay.has_value());
  CHECK(replay->target == "runs/a.log");
  CHECK(replay->speed == 10.0);
  CHECK(parse_transport_spec("replay:a.log")->speed == 1.0);
  for (const char* bad : {"can0", "tcp:1.2.3.4", "can:", "replay:a.log?speed=-1",
                          "replay:a.log?rate=2", "can:an-interface-name-too-long"}) {
    auto r = parse_transport_spec(bad);
    REQUIRE_FALSE(r.has_value());
    CHECK(r.error().code == ErrorCode::config);
    CHECK(r.error().message.starts_with("gyro_bus.transport: "));
  }
}

TEST_CASE("SocketCAN opens or fails as a value (this machine's kernel may have no CAN)") {
  const std::uint16_t ids[] = {0x101, 0x102};
  auto t = open_socketcan("fbnone0", ids);
  // Without CAN support: socket() fails; with it: the interface does not exist. Either way a
  // value, never an exception or a crash.
  REQUIRE_FALSE(t.has_value());
  CHECK((t.error().code == ErrorCode::connection || t.error().code == ErrorCode::io));
  CHECK(t.error().message.starts_with("can:fbnone0: "));
}

TEST_CASE("candump -l lines parse as candump writes them") {
  auto f = parse_candump_line("(1700000000.123456) can0 123#0102030405060708");
  REQUIRE(f.has_value());
  CHECK(f->time_us == 1700000000123456);
  CHECK(f->interface == "can0");
  CHECK(f->frame.can_id == 0x123u);
  CHECK(f->frame.can_dlc == 8);
  CHECK(f->frame.data[0] == 0x01);
  CHECK(f->frame.data[7] == 0x08);

  auto ext = parse_candump_line("(0000000001.000001) vcan0 1F334455#DEADBEEF");
  REQUIRE(ext.has_value());
  CHECK(ext->frame.can_id == (0x1F334455u | CAN_EFF_FLAG));
  CHECK(ext->frame.can_dlc == 4);

  auto rtr = parse_candump_line("(0000000001.000001) can0 123#R");
  REQUIRE(rtr.has_value());
  CHECK(rtr->frame.can_id == (0x123u | CAN_RTR_FLAG));

  auto empty = parse_candump_line("(0000000001.000001) can0 7FF#");
  REQUIRE(empty.has_value());
  CHECK(empty->frame.can_dlc == 0);

  for (const char* bad : {"", "can0 123#00", "(1.5) can0 123#00", "(1700000000.123456) can0 12#00",
                          "(1700000000.123456) can0 123##0112233", "(1700000000.123456) can0 123#0",
                          "(1700000000.123456) can0 123#001122334455667788", "(1700000000.123456) can0 800#00"}) {
    CHECK_FALSE(parse_candump_line(bad).has_value());
  }

  // Formatting writes what parsing reads.
  const can_frame g = can::encode({0x101, -7, 9, ok});
  const std::string line = format_candump_line(1700000000123456, "can0", g);
  CHECK(line.starts_with("(1700000000.123456) can0 101#F9FFFFFF0901"));
  auto back = parse_candump_line(line);
  REQUIRE(back.has_value());
  CHECK(std::memcmp(back->frame.data, g.data, 8) == 0);
  CHECK(back->frame.can_id == g.can_id);
}

TEST_CASE("candump lines the fuzzer found: overflowing stamps, remote lengths, error ids") {
  using namespace fogbench::drivers;
  // 9999999999999 s would overflow int64 microseconds: refused, not wrapped.
  CHECK_FALSE(parse_candump_line("(9999999999999.000000) can0 101#00"));
  // A remote frame keeps its requested length through format and parse.
  auto r = parse_candump_line("(1700000000.000004) can0 123#R5");
  REQUIRE(r);
  CHECK(r->frame.can_dlc == 5);
  auto again = parse_candump_line(format_candump_line(r->time_us, "can0", r->frame));
  REQUIRE(again);
  CHECK(again->frame.can_dlc == 5);
  CHECK(again->frame.can_id == r->frame.can_id);
  // An error frame's id may hold the error flag and classes, not the EFF and RTR flags.
  CHECK_FALSE(parse_candump_line("(1700000000.300000) vcan0 E0000001#C0C0010F"));
  CHECK(parse_candump_line("(1700000000.300000) vcan0 20000004#0000000000000000"));
}
