// Where gyro CAN frames come from, chosen by a configuration string, all feeding the same
// decode/filter/average path (GyroBus):
//   can:can0             SocketCAN raw socket, kernel filter on the units' ids
//   unix:/path           AF_UNIX SOCK_SEQPACKET, one 16-byte struct can_frame per datagram; the
//                        driver connects, the mock bench listens
//   replay:file.log      a candump -l log, replayed at the pace of its timestamps;
//                        replay:file.log?speed=10 ten times faster, ?speed=0 as fast as read
//   serial:/dev/ttyUSB0?baud=921600&framing=8E1
//                        one gyro's binary frames on a termios serial line, in the layout of
//                        gyro_bus.frame (serial_frame.hpp), handed on as that unit's CAN frames
#pragma once

#include <linux/can.h>
#include <termios.h>

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <set>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "fogbench/drivers/error.hpp"
#include "fogbench/drivers/sample_accumulator.hpp"
#include "fogbench/drivers/serial_frame.hpp"

namespace fogbench::drivers {

// A non-blocking source of frames with a file descriptor an event loop can wait on.
class CanTransport {
 public:
  virtual ~CanTransport() = default;

  // Readable when read() has frames to give.
  virtual int fd() const noexcept = 0;
  // Appends the frames available now, without blocking; 0 when there are none. Fails with
  // connection when the peer or interface is gone, end_of_stream when a replay has ended.
  virtual Result<std::size_t> read(std::vector<::can_frame>& out) = 0;
  // Datagrams of the wrong size or log lines that were not a frame, since opening.
  virtual std::uint64_t malformed() const noexcept = 0;
  virtual std::string describe() const = 0;

  // What the transport found wrong in the stream since the last call (a serial line's garbage,
  // CRC errors, cut frames, a silence that looks like a wrong baud rate), oldest first; each
  // message names the device. Empty for the transports whose frames carry no such news.
  struct Event {
    std::chrono::system_clock::time_point time;
    std::string message;
  };
  virtual std::vector<Event> take_events() { return {}; }

  // Called by GyroBus::close_samples once per sample period (the daemon's 1 s): a transport
  // that judges silence by samples rather than bytes (the serial one's dead line) counts here,
  // so no clock is read.
  virtual void sample_closed() noexcept {}

  // Called by GyroBus::reopen on the new transport with the one it replaces: a transport that
  // numbers frames itself (the serial one maps its counter onto 8 bits) carries its numbering
  // on, so a frame missed while the line was down is counted lost, not a jump of the counter.
  virtual void take_over(const CanTransport& previous) noexcept { (void)previous; }
};

// A serial line's character framing: data bits, parity, stop bits, written "8N1", "8E1", "7O2".
struct SerialFraming {
  int data_bits = 8;   // 7 or 8
  char parity = 'N';   // 'N' none, 'E' even, 'O' odd
  int stop_bits = 1;   // 1 or 2
  std::string to_string() const;  // "8N1"
  friend bool operator==(const SerialFraming&, const SerialFraming&) = default;
};

// Parses "8N1" (data bits 7|8, parity N|E|O, lower case accepted, stop bits 1|2); a `config`
// error naming `field` and which of the three characters is wrong otherwise.
Result<SerialFraming> parse_serial_framing(std::string_view text, const std::string& field);

// The framing's bits in a termios (CSIZE, PARENB, PARODD, CSTOPB; INPCK checked on input when
// there is parity, a byte with a parity error read as 0), and back: what a line holds.
void apply_serial_framing(::termios& t, const SerialFraming& framing) noexcept;
SerialFraming serial_framing_of(const ::termios& t) noexcept;

struct TransportSpec {
  enum class Kind { socketcan, unix_seqpacket, replay, serial };
  Kind kind = Kind::unix_seqpacket;
  std::string target;  // interface name, socket path, log file or serial device
  double speed = 1.0;  // replay only: 1 as recorded, 0 as fast as read
  int baud = 115200;   // serial only
  SerialFraming framing;  // serial only
};

// Parses "can:IFACE", "unix:PATH", "replay:FILE[?speed=N]",
// "serial:DEVICE[?baud=N][&framing=8N1]" (the serial options in either order, each at most
// once); a `config` error naming gyro_bus.transport (and the option) otherwise.
Result<TransportSpec> parse_transport_spec(std::string_view spec);

// Monotonic time for replay pacing; empty means std::chrono::steady_clock.
using MonotonicClock = std::function<std::chrono::nanoseconds()>;

Result<std::unique_ptr<CanTransport>> open_socketcan(const std::string& interface,
                                                     std::span<const std::uint16_t> node_ids);
Result<std::unique_ptr<CanTransport>> open_unix_seqpacket(const std::string& path);
Result<std::unique_ptr<CanTransport>> open_replay(const std::string& file, double speed,
                                                  MonotonicClock clock = {});
// `node_ids` feed the kernel filter where there is one (SocketCAN); the others deliver all.
Result<std::unique_ptr<CanTransport>> open_transport(const TransportSpec& spec,
                                                     std::span<const std::uint16_t> node_ids,
                                                     MonotonicClock clock = {});

// One part of a combined transport (combine_transports): its frames, limited to `only` (a serial
// line's unit), or, with `only` empty, every frame whose id no other part owns (the CAN bus
// beside serial gyros: a unit read on its own line is not also taken from the bus).
struct TransportPart {
  std::unique_ptr<CanTransport> transport;
  std::set<std::uint16_t> only;
};

// Several transports read as one: fd() is an epoll descriptor readable while any part is;
// read() reads every part (the first part's error fails the read, naming it); malformed(),
// take_events() and sample_closed() sum, join and forward in the parts' order; take_over()
// hands each part on to the part at the same place. GyroBus::open makes one for a bench whose
// units have serial lines of their own (GyroBusConfig::lines).
Result<std::unique_ptr<CanTransport>> combine_transports(std::vector<TransportPart> parts);

// Whether termios has a speed constant for this baud rate (1200..4000000).
bool serial_baud_supported(int baud) noexcept;

// One gyro on a serial line (raw, at `baud` with `framing`; parity checked on input, a byte
// with a parity error read as 0 so its frame fails its CRC): its bytes go through serial::Decoder and each
// good frame becomes a CAN frame of `unit.node_id` (counts = rate / unit.scale_dph_per_count,
// the sequence mapped onto 8 bits, status `valid` from the frame's valid mask), each corrupt
// frame (CRC, cut, non-finite or out-of-range rate) a frame of that id with DLC 0, so
// SampleAccumulator counts lost, corrupt and repeated frames exactly as for CAN. `unit` must be
// in rate mode, and 7 data bits need a sync word of bytes below 0x80 (a `config` error
// otherwise). Problems come out of take_events(); a line that delivers no byte at all over
// `dead_line_samples` sample periods in a row (sample_closed()) raises a dead_line event, once
// per silence, so a dead line is told from a wrong baud rate (bytes, but no frame: no_frame).
inline constexpr int kDeadLineSamples = 5;
Result<std::unique_ptr<CanTransport>> open_serial_gyro(const std::string& device, int baud,
                                                       const SerialFraming& framing,
                                                       serial::FrameFormat format,
                                                       const GyroChannelConfig& unit,
                                                       int dead_line_samples = kDeadLineSamples);

}  // namespace fogbench::drivers
