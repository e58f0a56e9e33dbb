// The serial gyro transport on a pseudo-terminal pair: the test writes frames (and garbage, a CRC
// error, a cut frame, noise) on the master side, GyroBus reads the slave as a termios serial
// device and accounts the frames exactly as CAN ones.
#include <catch2/catch.hpp>

#include <fcntl.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <stdlib.h>
#include <termios.h>
#include <unistd.h>

#include <nlohmann/json.hpp>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "fogbench/drivers/can_frame.hpp"
#include "fogbench/drivers/gyro_bus.hpp"
#include "fogbench/drivers/serial_frame.hpp"

using namespace fogbench::drivers;
using nlohmann::json;

namespace {

struct Pty {
  int master = -1;
  std::string slave;
  Pty() {
    master = ::posix_openpt(O_RDWR | O_NOCTTY);
    REQUIRE(master >= 0);
    REQUIRE(::grantpt(master) == 0);
    REQUIRE(::unlockpt(master) == 0);
    slave = ::ptsname(master);
  }
  ~Pty() { close(); }
  void close() {
    if (master >= 0) ::close(master);
    master = -1;
  }
  void write(const std::vector<std::uint8_t>& bytes) const {
    std::size_t done = 0;
    while (done < bytes.size()) {
      const auto n = ::write(master, bytes.data() + done, bytes.size() - done);
      REQUIRE(n > 0);
      done += static_cast<std::size_t>(n);
    }
  }
};

serial::FrameFormat kvh() {
  std::ifstream in(FOGBENCH_SOURCE_DIR "/drivers/examples/kvh-1775-format-a.json");
  REQUIRE(in);
  auto f = serial::parse_frame_format(json::parse(in), "frame");
  REQUIRE(f.has_value());
  return *f;
}

GyroChannelConfig unit() {
  GyroChannelConfig u;
  u.node_id = 0x101;
  u.mode = GyroMode::rate;
  u.scale_dph_per_count = 0.001;
  u.startup_flag = false;
  return u;
}

// Reads until `want` frames came or the line stays quiet for 2 s (a failure, not a timing
// assertion: the bytes are already written).
std::vector<::can_frame> read_frames(GyroBus& bus, std::size_t want) {
  std::vector<::can_frame> all, batch;
  while (all.size() < want) {
    pollfd p{bus.fd(), POLLIN, 0};
    if (::poll(&p, 1, 2000) <= 0) break;
    auto n = bus.read_frames(batch);
    REQUIRE(n.has_value());
    all.insert(all.end(), batch.begin(), batch.end());
  }
  return all;
}

}  // namespace

TEST_CASE("serial transport strings parse with a baud rate and refuse bad ones", "[serial][transport]") {
  auto s = parse_transport_spec("serial:/dev/ttyUSB0?baud=921600");
  REQUIRE(s.has_value());
  CHECK(s->kind == TransportSpec::Kind::serial);
  CHECK(s->target == "/dev/ttyUSB0");
  CHECK(s->baud == 921600);
  CHECK(parse_transport_spec("serial:/dev/ttyUSB0")->baud == 115200);
  CHECK_FALSE(parse_transport_spec("serial:/dev/ttyUSB0?baud=12345").has_value());
  CHECK_FALSE(parse_transport_spec("serial:/dev/ttyUSB0?parity=even").has_value());
  CHECK_FALSE(parse_transport_spec("serial:").has_value());
}

TEST_CASE("serial framing: 8N1 by default, 8E1 7O2 and the like parsed, each bad character named", "[serial][transport]") {
  auto s = parse_transport_spec("serial:/dev/ttyUSB0?baud=921600");
  REQUIRE(s.has_value());
  CHECK(s->framing == SerialFraming{8, 'N', 1});
  CHECK(s->framing.to_string() == "8N1");
  s = parse_transport_spec("serial:/dev/ttyUSB0?baud=460800&framing=8E1");
  REQUIRE(s.has_value());
  CHECK(s->baud == 460800);
  CHECK(s->framing == SerialFraming{8, 'E', 1});
  s = parse_transport_spec("serial:/dev/ttyUSB0?framing=7o2&baud=9600");
  REQUIRE(s.has_value());
  CHECK(s->baud == 9600);
  CHECK(s->framing.to_string() == "7O2");
  CHECK(s->target == "/dev/ttyUSB0");

  const auto error_of = [](std::string_view spec) {
    auto r = parse_transport_spec(spec);
    REQUIRE_FALSE(r.has_value());
    CHECK(r.error().code == ErrorCode::config);
    return r.error().message;
  };
  CHECK(error_of("serial:/dev/ttyUSB0?framing=9N1").starts_with("gyro_bus.transport: framing: '9N1': data bits '9' is not 7 or 8"));
  CHECK(error_of("serial:/dev/ttyUSB0?framing=8M1").starts_with("gyro_bus.transport: framing: '8M1': parity 'M' is not N (none), E (even) or O (odd)"));
  CHECK(error_of("serial:/dev/ttyUSB0?framing=8N3").starts_with("gyro_bus.transport: framing: '8N3': stop bits '3' is not 1 or 2"));
  CHECK(error_of("serial:/dev/ttyUSB0?framing=8N1.5").starts_with("gyro_bus.transport: framing: '8N1.5': expected 3 characters"));
  CHECK(error_of("serial:/dev/ttyUSB0?framing=8N1&framing=8E1").starts_with("gyro_bus.transport: framing given twice"));
  CHECK(error_of("serial:/dev/ttyUSB0?baud=9600&baud=9600").starts_with("gyro_bus.transport: baud given twice"));
  CHECK(error_of("serial:/dev/ttyUSB0?baud=9600&parity=E").starts_with("gyro_bus.transport: unknown serial option 'parity=E'"));
  CHECK(error_of("serial:/dev/ttyUSB0?framing=8X1").find("in 'serial:/dev/ttyUSB0?framing=8X1'") != std::string::npos);
}

TEST_CASE("a framing's termios bits, set and read back", "[serial][transport]") {
  struct Case {
    const char* framing;
    tcflag_t size, parity, stop;
  };
  const Case cases[] = {{"8N1", CS8, 0, 0}, {"8E1", CS8, PARENB, 0}, {"8O2", CS8, PARENB | PARODD, CSTOPB},
                        {"7E1", CS7, PARENB, 0}, {"7O2", CS7, PARENB | PARODD, CSTOPB}, {"8N2", CS8, 0, CSTOPB}};
  for (const auto& c : cases) {
    INFO(c.framing);
    auto f = parse_serial_framing(c.framing, "framing");
    REQUIRE(f.has_value());
    termios t{};
    ::cfmakeraw(&t);
    t.c_cflag |= CS5 | PARODD | CSTOPB;  // whatever was there before is replaced
    apply_serial_framing(t, *f);
    CHECK((t.c_cflag & CSIZE) == c.size);
    CHECK((t.c_cflag & (PARENB | PARODD)) == c.parity);
    CHECK((t.c_cflag & CSTOPB) == c.stop);
    CHECK((t.c_cflag & (CREAD | CLOCAL)) == (CREAD | CLOCAL));
    CHECK(((t.c_iflag & INPCK) != 0) == (c.parity != 0));
    CHECK((t.c_iflag & (IGNPAR | PARMRK)) == 0);
    CHECK(serial_framing_of(t) == *f);
  }
}

TEST_CASE("the framing on a pty pair: stop bits and baud held, what the pty drops reported as an event", "[serial][transport]") {
  struct Case {
    const char* framing;
    const char* held;  // Linux's pty forces CS8 and clears PARENB (drivers/tty/pty.c, pty_set_termios)
    tcflag_t stop;
  };
  const Case cases[] = {{"8N1", "8N1", 0}, {"8N2", "8N2", CSTOPB}, {"8E1", "8N1", 0}, {"7O2", "8N2", CSTOPB}};
  for (const auto& c : cases) {
    INFO(c.framing);
    Pty pty;
    auto format = kvh();
    format.sync = {0x7E, 0x55};  // 7 data bits carry no byte >= 0x80
    GyroBusConfig cfg;
    cfg.transport = "serial:" + pty.slave + "?baud=57600&framing=" + c.framing;
    cfg.frame = format;
    auto bus = GyroBus::open(cfg, {unit()});
    INFO((bus ? std::string() : bus.error().message));
    REQUIRE(bus.has_value());
    // A pty master reads its slave's termios (Linux): what the driver set, as the pty kept it.
    termios t{};
    REQUIRE(::tcgetattr(pty.master, &t) == 0);
    CHECK((t.c_cflag & CSTOPB) == c.stop);
    CHECK(::cfgetispeed(&t) == B57600);
    CHECK(serial_framing_of(t).to_string() == c.held);
    CHECK(bus->transport().describe().find(std::string("57600 baud ") + c.framing) != std::string::npos);
    const auto events = bus->take_events();
    if (std::string(c.framing) == c.held) {
      CHECK(events.empty());
    } else {
      REQUIRE(events.size() == 1);
      CHECK(events[0].message.find(pty.slave) != std::string::npos);
      CHECK(events[0].message.find(std::string("the device holds ") + c.held + ", not the configured " + c.framing) !=
            std::string::npos);
    }
  }
  Pty pty;
  GyroBusConfig cfg;
  cfg.transport = "serial:" + pty.slave + "?framing=7E1";
  cfg.frame = kvh();  // sync 0xFE81FF55
  auto refused = GyroBus::open(cfg, {unit()});
  REQUIRE_FALSE(refused.has_value());
  CHECK(refused.error().code == ErrorCode::config);
  CHECK(refused.error().message.find("framing 7E1: 7 data bits cannot carry the frame's sync word") != std::string::npos);
}

TEST_CASE("a serial gyro on a pty feeds the CAN accounting: lost, corrupt, garbage and reasons", "[serial][transport]") {
  Pty pty;
  const auto format = kvh();
  GyroBusConfig cfg;
  cfg.transport = "serial:" + pty.slave + "?baud=921600";
  cfg.frame = format;
  auto bus = GyroBus::open(cfg, {unit()});
  REQUIRE(bus.has_value());

  std::vector<std::uint8_t> stream;
  const auto frame = [&](std::uint32_t seq) {
    return serial::encode(format, {.rate_dph = 36.0, .sequence = seq, .status = 1, .valid = true});
  };
  const auto add = [&](const std::vector<std::uint8_t>& b) { stream.insert(stream.end(), b.begin(), b.end()); };
  add(frame(0));
  add(frame(1));
  add({0x11, 0x22, 0x33});  // garbage between frames
  add(frame(2));
  auto bad = frame(3);
  bad[20] ^= 0x40;           // CRC error
  add(bad);
  add(frame(5));             // 4 missing: lost
  auto cut = frame(6);
  cut.resize(17);            // cut in half
  add(cut);
  add(frame(7));
  pty.write(stream);

  const auto frames = read_frames(*bus, 7);  // 5 good, 2 corrupt
  CHECK(frames.size() == 7);
  const auto sample = bus->close_samples();
  REQUIRE(sample.units.size() == 1);
  const auto& u = sample.units[0];
  CHECK(u.frames == 5);
  CHECK(u.frames_used == 5);
  CHECK(u.frames_corrupt == 2);
  CHECK(u.frames_lost == 1);
  REQUIRE(u.rate_dph.has_value());
  CHECK(*u.rate_dph == Approx(36.0));
  CHECK(sample.malformed_total == 1);  // one garbage run

  auto events = bus->take_events();
  REQUIRE(events.size() == 3);
  CHECK(events[0].message.find(pty.slave) != std::string::npos);
  CHECK(events[0].message.find("garbage at byte 72: 3 bytes") != std::string::npos);
  CHECK(events[1].message.find("bad_crc at byte 111") != std::string::npos);
  CHECK(events[2].message.find("cut at byte 183") != std::string::npos);
  CHECK(events[0].time.time_since_epoch().count() > 0);
}

TEST_CASE("bytes at a wrong baud rate are a reported reason, and a closed line a connection error", "[serial][transport]") {
  Pty pty;
  GyroBusConfig cfg;
  cfg.transport = "serial:" + pty.slave + "?baud=115200";
  cfg.frame = kvh();
  auto bus = GyroBus::open(cfg, {unit()});
  REQUIRE(bus.has_value());
  // What a 921600-baud frame stream looks like read at 115200: bytes, never the sync word.
  std::vector<std::uint8_t> noise;
  std::uint32_t x = 99;
  for (int i = 0; i < 600; ++i) {
    x = x * 1103515245u + 12345u;
    noise.push_back(static_cast<std::uint8_t>((x >> 16) & 0x7F));  // no 0xFE: never a sync
  }
  pty.write(noise);
  std::vector<::can_frame> batch;
  std::size_t seen = 0;
  std::vector<CanTransport::Event> events;
  while (events.empty()) {
    pollfd p{bus->fd(), POLLIN, 0};
    if (::poll(&p, 1, 2000) <= 0) break;
    auto n = bus->read_frames(batch);
    REQUIRE(n.has_value());
    seen += batch.size();
    for (auto& e : bus->take_events()) events.push_back(e);
  }
  CHECK(seen == 0);
  REQUIRE_FALSE(events.empty());
  bool no_frame = false;
  for (const auto& e : events) {
    if (e.message.find("no_frame") != std::string::npos && e.message.find("wrong baud rate") != std::string::npos &&
        e.message.find(pty.slave) != std::string::npos && e.message.find("0 sync words seen") != std::string::npos &&
        e.message.find("; configured 115200 baud 8N1") != std::string::npos) {
      no_frame = true;
    }
  }
  CHECK(no_frame);
  const auto sample = bus->close_samples();
  CHECK(sample.units[0].frames == 0);
  CHECK_FALSE(sample.units[0].rate_dph.has_value());

  pty.close();
  auto gone = bus->read_frames(batch);
  REQUIRE_FALSE(gone.has_value());
  CHECK(gone.error().code == ErrorCode::connection);
}

TEST_CASE("a serial gyro bus refuses a missing frame, two units and a device that is not there", "[serial][transport]") {
  GyroBusConfig cfg;
  cfg.transport = "serial:/dev/nonexistent-fogbench-tty";
  CHECK(GyroBus::open(cfg, {unit()}).error().code == ErrorCode::config);
  cfg.frame = kvh();
  auto u2 = unit();
  u2.node_id = 0x102;
  CHECK(GyroBus::open(cfg, {unit(), u2}).error().code == ErrorCode::config);
  auto missing = GyroBus::open(cfg, {unit()});
  REQUIRE_FALSE(missing.has_value());
  CHECK(missing.error().code == ErrorCode::connection);
  CHECK(missing.error().message.find("/dev/nonexistent-fogbench-tty") != std::string::npos);
}

TEST_CASE("a reopened serial line carries the 7-bit counter on: the frames missed meanwhile are lost, no more", "[serial][transport]") {
  Pty first;
  const auto format = kvh();
  GyroBusConfig cfg;
  cfg.transport = "serial:" + first.slave;
  cfg.frame = format;
  auto bus = GyroBus::open(cfg, {unit()});
  REQUIRE(bus.has_value());
  const auto frame = [&](std::uint32_t seq) {
    return serial::encode(format, {.rate_dph = 1.0, .sequence = seq, .status = 1, .valid = true});
  };
  std::vector<std::uint8_t> stream;
  for (std::uint32_t s : {125u, 126u, 127u}) {
    const auto f = frame(s);
    stream.insert(stream.end(), f.begin(), f.end());
  }
  first.write(stream);
  CHECK(read_frames(*bus, 3).size() == 3);

  Pty second;  // the line comes back on another device (a USB adapter re-enumerated)
  cfg.transport = "serial:" + second.slave;
  REQUIRE(bus->reopen(cfg).has_value());
  stream.clear();
  for (std::uint32_t s : {2u, 3u}) {  // 0 and 1 were sent while the line was down
    const auto f = frame(s);
    stream.insert(stream.end(), f.begin(), f.end());
  }
  second.write(stream);
  CHECK(read_frames(*bus, 2).size() == 2);
  const auto sample = bus->close_samples();
  CHECK(sample.units[0].frames == 5);
  CHECK(sample.units[0].frames_lost == 2);
}

TEST_CASE("a line that sends no byte is a dead_line after 5 sample periods, told from a wrong baud rate", "[serial][transport]") {
  Pty pty;
  const auto format = kvh();
  GyroBusConfig cfg;
  cfg.transport = "serial:" + pty.slave + "?baud=460800&framing=8E1";
  cfg.frame = format;
  auto bus = GyroBus::open(cfg, {unit()});
  REQUIRE(bus.has_value());
  (void)bus->take_events();  // the pty holds 8N1, not 8E1: reported at open
  const auto dead_lines = [&] {
    std::size_t n = 0;
    for (const auto& e : bus->take_events()) {
      if (e.message.find("dead_line") == std::string::npos) continue;
      ++n;
      CHECK(e.message.find(pty.slave) != std::string::npos);
      CHECK(e.message.find("no byte received in 5 sample periods in a row") != std::string::npos);
      CHECK(e.message.find("configured 460800 baud 8E1") != std::string::npos);
    }
    return n;
  };
  for (int i = 0; i < 4; ++i) bus->close_samples();
  CHECK(dead_lines() == 0);
  bus->close_samples();
  CHECK(dead_lines() == 1);
  for (int i = 0; i < 10; ++i) bus->close_samples();
  CHECK(dead_lines() == 0);  // once per silence

  // Bytes, even without a frame, end the silence: the next one is reported again.
  pty.write({0x01, 0x02});
  std::vector<::can_frame> batch;
  pollfd p{bus->fd(), POLLIN, 0};
  REQUIRE(::poll(&p, 1, 2000) == 1);
  REQUIRE(bus->read_frames(batch).has_value());
  bus->close_samples();
  for (int i = 0; i < 4; ++i) bus->close_samples();
  CHECK(dead_lines() == 0);
  bus->close_samples();
  CHECK(dead_lines() == 1);
}

TEST_CASE("two serial gyros and a CAN bus in one GyroBus: each unit from its own line, the bus's copy left out", "[serial][transport]") {
  char tmpl[] = "/tmp/fogbench-lines-XXXXXX";
  REQUIRE(::mkdtemp(tmpl) != nullptr);
  const std::filesystem::path dir = tmpl;
  const auto sock = (dir / "can.sock").string();
  // The bus's side: a SEQPACKET listener, as the mock bench's CAN socket.
  const int listener = ::socket(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC, 0);
  REQUIRE(listener >= 0);
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  std::strncpy(addr.sun_path, sock.c_str(), sizeof addr.sun_path - 1);
  REQUIRE(::bind(listener, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0);
  REQUIRE(::listen(listener, 1) == 0);

  Pty a, b;
  const auto format = kvh();
  GyroBusConfig cfg;
  cfg.transport = "unix:" + sock;
  cfg.lines.push_back({0x101, "serial:" + a.slave + "?baud=921600", format, "", "units[0].gyro_line"});
  cfg.lines.push_back({0x102, "serial:" + b.slave + "?baud=460800&framing=8N2", format, "", "units[1].gyro_line"});
  auto u1 = unit();
  auto u2 = unit();
  u2.node_id = 0x102;
  auto u3 = unit();
  u3.node_id = 0x103;
  auto bus = GyroBus::open(cfg, {u1, u2, u3});
  REQUIRE(bus.has_value());
  const int peer = ::accept(listener, nullptr, nullptr);
  REQUIRE(peer >= 0);
  CHECK(bus->transport().describe() == "unix:" + sock + " + serial:" + a.slave + " (921600 baud 8N1, node 257) + serial:" +
                                           b.slave + " (460800 baud 8N2, node 258)");

  const auto frame = [&](double dph, std::uint32_t seq) {
    return serial::encode(format, {.rate_dph = dph, .sequence = seq, .status = 1, .valid = true});
  };
  // Line A: 3 frames, garbage before the third. Line B: 3 frames, the second with a bad CRC.
  std::vector<std::uint8_t> sa, sb;
  for (std::uint32_t i = 0; i < 3; ++i) {
    if (i == 2) sa.insert(sa.end(), {0x01, 0x02});
    const auto fa = frame(10.0, i);
    sa.insert(sa.end(), fa.begin(), fa.end());
    auto fb = frame(20.0, i);
    if (i == 1) fb[35] ^= 0x01;
    sb.insert(sb.end(), fb.begin(), fb.end());
  }
  a.write(sa);
  b.write(sb);
  // The bus: unit 0x103's frames, a copy of unit 0x101's (read on its line: left out), a stranger.
  const auto send = [&](const can_frame& f) { REQUIRE(::send(peer, &f, sizeof f, 0) == static_cast<ssize_t>(sizeof f)); };
  send(can::encode({0x103, 30000, 0, can::status::valid}));
  send(can::encode({0x103, 30000, 1, can::status::valid}));
  send(can::encode({0x101, 999999, 7, can::status::valid}));
  send(can::encode({0x200, 1, 0, can::status::valid}));

  std::vector<::can_frame> all, batch;
  while (all.size() < 9) {  // 3 + 3 (one corrupt) from the lines, 2 + the stranger from the bus
    pollfd p{bus->fd(), POLLIN, 0};
    if (::poll(&p, 1, 2000) <= 0) break;
    auto n = bus->read_frames(batch);
    REQUIRE(n.has_value());
    all.insert(all.end(), batch.begin(), batch.end());
  }
  CHECK(all.size() == 9);
  const auto s = bus->close_samples();
  REQUIRE(s.units.size() == 3);
  CHECK(s.units[0].frames == 3);
  CHECK(s.units[0].frames_lost == 0);
  REQUIRE(s.units[0].rate_dph.has_value());
  CHECK(*s.units[0].rate_dph == Approx(10.0));  // the bus's copy (999999 counts) never reached it
  CHECK(s.units[1].frames == 2);
  CHECK(s.units[1].frames_corrupt == 1);
  CHECK(*s.units[1].rate_dph == Approx(20.0));
  CHECK(s.units[2].frames == 2);
  CHECK(*s.units[2].rate_dph == Approx(30.0));
  CHECK(s.frames_foreign == 1);
  CHECK(s.malformed_total == 1);  // line A's garbage run
  const auto events = bus->take_events();
  REQUIRE(events.size() == 2);
  CHECK(events[0].message.find("serial:" + a.slave) != std::string::npos);
  CHECK(events[0].message.find("garbage at byte 72: 2 bytes") != std::string::npos);
  CHECK(events[1].message.find("serial:" + b.slave) != std::string::npos);
  CHECK(events[1].message.find("bad_crc at byte 36") != std::string::npos);

  // A line unplugged: the read fails naming it; reopen() reopens every part and each line's
  // counter carries on (the frame sent while it was down counts lost).
  Pty a2;
  a.close();
  auto gone = bus->read_frames(batch);
  REQUIRE_FALSE(gone.has_value());
  CHECK(gone.error().message.find(a.slave) != std::string::npos);
  ::close(peer);
  cfg.lines[0].transport = "serial:" + a2.slave;
  REQUIRE(bus->reopen(cfg).has_value());
  const int peer2 = ::accept(listener, nullptr, nullptr);
  REQUIRE(peer2 >= 0);
  a2.write(frame(10.0, 4));  // 3 was sent while the line was down
  std::size_t got = 0;
  while (got < 1) {
    pollfd p{bus->fd(), POLLIN, 0};
    if (::poll(&p, 1, 2000) <= 0) break;
    auto n = bus->read_frames(batch);
    REQUIRE(n.has_value());
    got += *n;
  }
  CHECK(got == 1);
  const auto after = bus->close_samples();
  CHECK(after.units[0].frames == 1);
  CHECK(after.units[0].frames_lost == 1);
  ::close(peer2);
  ::close(listener);
  std::filesystem::remove_all(dir);
}

TEST_CASE("a bus of serial lines refuses a unit with neither line nor bus, and a serial bus beside lines", "[serial][transport]") {
  Pty a;
  GyroBusConfig cfg;
  cfg.lines.push_back({0x101, "serial:" + a.slave, kvh(), "", "units[0].gyro_line"});
  auto u2 = unit();
  u2.node_id = 0x102;
  auto r = GyroBus::open(cfg, {unit(), u2});
  REQUIRE_FALSE(r.has_value());
  CHECK(r.error().message == "gyro_bus: node 258 has no serial line of its own and gyro_bus.transport is empty");
  cfg.transport = "serial:/dev/ttyUSB9";
  r = GyroBus::open(cfg, {unit(), u2});
  REQUIRE_FALSE(r.has_value());
  CHECK(r.error().message.starts_with("gyro_bus: a serial: gyro_bus.transport carries one unit"));
  cfg.transport.clear();
  auto alone = GyroBus::open(cfg, {unit()});  // every unit on a line: no bus needed
  REQUIRE(alone.has_value());
}
