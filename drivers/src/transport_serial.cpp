// One gyro's binary frames on a termios serial line, decoded by serial::Decoder and handed on as
// the unit's CAN frames, so the same SampleAccumulator accounting applies.
#include <fcntl.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <limits>
#include <memory>
#include <optional>
#include <utility>
#include <vector>
#include <chrono>

#include "fogbench/drivers/can_frame.hpp"
#include "fogbench/drivers/can_transport.hpp"
#include "termios_baud.hpp"

namespace fogbench::drivers {

namespace {

class SerialGyroTransport final : public CanTransport {
 public:
  SerialGyroTransport(int fd, std::string name, std::string line, serial::FrameFormat format,
                      GyroChannelConfig unit, int dead_line_samples)
      : fd_(fd),
        name_(std::move(name)),
        line_(std::move(line)),
        dead_line_samples_(dead_line_samples),
        decoder_(std::move(format)),
        sequence_(decoder_.format().sequence_modulo),
        unit_(unit) {}
  ~SerialGyroTransport() override { ::close(fd_); }

  int fd() const noexcept override { return fd_; }
  std::uint64_t malformed() const noexcept override { return garbage_runs_; }
  std::string describe() const override { return name_; }
  std::vector<Event> take_events() override { return std::exchange(events_, {}); }
  void sample_closed() noexcept override {
    if (bytes_since_close_ > 0) {
      bytes_since_close_ = 0;
      quiet_samples_ = 0;
      dead_reported_ = false;
      return;
    }
    if (++quiet_samples_ < dead_line_samples_ || dead_reported_) return;
    dead_reported_ = true;
    try {
      events_.push_back({std::chrono::system_clock::now(),
                         name_ + ": dead_line: no byte received in " + std::to_string(quiet_samples_) +
                             " sample periods in a row (" + std::to_string(bytes_total_) +
                             " bytes since the line was opened; configured " + line_ +
                             "): a silent line (cable, the gyro's power or its TX/RX wiring, the wrong device), not "
                             "a baud rate: a wrong baud rate still delivers bytes, reported as no_frame"});
    } catch (...) {
      // Out of memory for a message: the samples without frames say it all the same.
    }
  }
  void add_events(std::vector<Event> events) {
    for (auto& e : events) events_.push_back(std::move(e));
  }
  void take_over(const CanTransport& previous) noexcept override {
    if (const auto* old = dynamic_cast<const SerialGyroTransport*>(&previous)) {
      if (old->decoder_.format().sequence_modulo == decoder_.format().sequence_modulo) sequence_ = old->sequence_;
      next_sequence_ = old->next_sequence_;
    }
  }

  Result<std::size_t> read(std::vector<::can_frame>& out) override {
    std::uint8_t buf[4096];
    std::size_t got = 0;
    for (;;) {
      const ssize_t n = ::read(fd_, buf, sizeof buf);
      if (n > 0) {
        bytes_since_close_ += static_cast<std::size_t>(n);
        bytes_total_ += static_cast<std::uint64_t>(n);
        got += handle(std::span<const std::uint8_t>(buf, static_cast<std::size_t>(n)), out);
        continue;
      }
      if (n < 0 && errno == EINTR) continue;
      if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) break;
      // 0 (hang-up) or EIO (the other end of a pty closed, a USB adapter unplugged).
      const std::string why = n == 0 ? "hang-up" : std::strerror(errno);
      if (got > 0) break;  // hand over what arrived; the error repeats on the next call
      return fail(ErrorCode::connection, name_ + ": read: " + why);
    }
    return got;
  }

 private:
  std::size_t handle(std::span<const std::uint8_t> bytes, std::vector<::can_frame>& out) {
    scratch_.clear();
    decoder_.feed(bytes, scratch_);
    std::size_t got = 0;
    const auto now = std::chrono::system_clock::now();
    for (const auto& e : scratch_) {
      if (e.kind == serial::Event::Kind::frame) {
        const double counts = std::nearbyint(e.frame.rate_dph / unit_.scale_dph_per_count);
        if (!(std::abs(counts) <= std::numeric_limits<std::int32_t>::max())) {
          events_.push_back({now, name_ + ": frame at byte " + std::to_string(e.offset) + ": rate " +
                                      format_number(e.frame.rate_dph) +
                                      " deg/h beyond the int32 counts of the unit's scale_dph_per_count " +
                                      format_number(unit_.scale_dph_per_count) + " (counted corrupt)"});
          out.push_back(corrupt_frame());
          ++got;
          continue;
        }
        can::GyroFrame f;
        f.node_id = unit_.node_id;
        f.counts = static_cast<std::int32_t>(counts);
        f.sequence = decoder_.format().sequence ? sequence_.map(e.frame.sequence) : next_sequence_++;
        f.status = e.frame.valid ? can::status::valid : std::uint8_t{0};
        out.push_back(can::encode(f));
        ++got;
        continue;
      }
      if (e.kind == serial::Event::Kind::garbage) ++garbage_runs_;
      if (e.kind == serial::Event::Kind::bad_crc || e.kind == serial::Event::Kind::cut ||
          e.kind == serial::Event::Kind::bad_value) {
        out.push_back(corrupt_frame());
        ++got;
      }
      if (e.kind == serial::Event::Kind::no_frame) {
        events_.push_back({now, name_ + ": " + serial::describe(e) + "; configured " + line_});
      } else {
        events_.push_back({now, name_ + ": " + serial::describe(e)});
      }
    }
    return got;
  }

  ::can_frame corrupt_frame() const noexcept {
    ::can_frame f{};
    f.can_id = unit_.node_id;
    f.len = 0;  // a gyro frame always has 8 bytes: SampleAccumulator counts this one corrupt
    return f;
  }

  int fd_;
  std::string name_;
  std::string line_;  // "921600 baud 8N1"
  int dead_line_samples_;
  serial::Decoder decoder_;
  serial::SequenceMapper sequence_;
  GyroChannelConfig unit_;
  std::size_t bytes_since_close_ = 0;
  std::uint64_t bytes_total_ = 0;
  int quiet_samples_ = 0;
  bool dead_reported_ = false;
  std::uint8_t next_sequence_ = 0;  // a format without a counter: no loss can be seen
  std::uint64_t garbage_runs_ = 0;
  std::vector<serial::Event> scratch_;
  std::vector<Event> events_;
};

}  // namespace

void apply_serial_framing(::termios& t, const SerialFraming& framing) noexcept {
  t.c_cflag &= ~static_cast<tcflag_t>(CSIZE | PARENB | PARODD | CSTOPB);
  t.c_cflag |= (framing.data_bits == 7 ? CS7 : CS8) | CLOCAL | CREAD;
  if (framing.parity != 'N') {
    t.c_cflag |= PARENB;
    if (framing.parity == 'O') t.c_cflag |= PARODD;
    // Checked on input; neither ignored nor marked, so a byte with a parity error reads as 0 and
    // its frame fails its CRC (counted corrupt).
    t.c_iflag |= INPCK;
    t.c_iflag &= ~static_cast<tcflag_t>(IGNPAR | PARMRK);
  } else {
    t.c_iflag &= ~static_cast<tcflag_t>(INPCK);
  }
  if (framing.stop_bits == 2) t.c_cflag |= CSTOPB;
}

SerialFraming serial_framing_of(const ::termios& t) noexcept {
  SerialFraming f;
  const auto size = t.c_cflag & CSIZE;
  f.data_bits = size == CS5 ? 5 : size == CS6 ? 6 : size == CS7 ? 7 : 8;
  f.parity = (t.c_cflag & PARENB) == 0 ? 'N' : (t.c_cflag & PARODD) != 0 ? 'O' : 'E';
  f.stop_bits = (t.c_cflag & CSTOPB) != 0 ? 2 : 1;
  return f;
}

bool serial_baud_supported(int baud) noexcept { return detail::termios_baud(baud).has_value(); }

Result<std::unique_ptr<CanTransport>> open_serial_gyro(const std::string& device, int baud,
                                                       const SerialFraming& framing,
                                                       serial::FrameFormat format,
                                                       const GyroChannelConfig& unit, int dead_line_samples) {
  const std::string line = std::to_string(baud) + " baud " + framing.to_string();
  const std::string name = "serial:" + device + " (" + line + ", node " + std::to_string(unit.node_id) + ")";
  if (dead_line_samples < 1) return fail(ErrorCode::config, name + ": dead_line_samples must be at least 1");
  if (unit.mode != GyroMode::rate || !(unit.scale_dph_per_count > 0)) {
    return fail(ErrorCode::config, name + ": a serial gyro's unit must be in rate mode with scale_dph_per_count > 0");
  }
  const auto speed = detail::termios_baud(baud);
  if (!speed) return fail(ErrorCode::config, name + ": baud rate not supported");
  if ((framing.data_bits != 7 && framing.data_bits != 8) ||
      (framing.parity != 'N' && framing.parity != 'E' && framing.parity != 'O') ||
      (framing.stop_bits != 1 && framing.stop_bits != 2)) {
    return fail(ErrorCode::config, name + ": framing must be 7 or 8 data bits, parity N, E or O, 1 or 2 stop bits");
  }
  if (framing.data_bits == 7) {
    for (const auto b : format.sync) {
      if (b >= 0x80) {
        return fail(ErrorCode::config, name + ": framing " + framing.to_string() +
                                           ": 7 data bits cannot carry the frame's sync word (a byte >= 0x80)");
      }
    }
  }
  const int fd = ::open(device.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) return fail(ErrorCode::connection, name + ": open: " + std::strerror(errno));
  termios t{};
  if (::tcgetattr(fd, &t) != 0) {
    const std::string why = std::strerror(errno);
    ::close(fd);
    return fail(ErrorCode::io, name + ": tcgetattr (not a serial device?): " + why);
  }
  ::cfmakeraw(&t);
  ::cfsetispeed(&t, *speed);
  ::cfsetospeed(&t, *speed);
  apply_serial_framing(t, framing);
  if (::tcsetattr(fd, TCSANOW, &t) != 0) {
    const std::string why = std::strerror(errno);
    ::close(fd);
    return fail(ErrorCode::io, name + ": tcsetattr: " + why);
  }
  // tcsetattr succeeds when any one change took, and a pseudo-terminal keeps neither parity nor
  // data bits (Linux's pty forces CS8, no parity): read back what the line holds and say so.
  std::vector<CanTransport::Event> opened;
  termios held{};
  if (::tcgetattr(fd, &held) == 0) {
    const auto now = serial_framing_of(held);
    if (now != framing) {
      opened.push_back({std::chrono::system_clock::now(),
                        name + ": the device holds " + now.to_string() + ", not the configured " + framing.to_string() +
                            " (a pseudo-terminal keeps no parity or data bits; a UART that does not is misconfigured)"});
    }
  }
  auto transport = std::make_unique<SerialGyroTransport>(fd, name, line, std::move(format), unit, dead_line_samples);
  transport->add_events(std::move(opened));
  return transport;
}

}  // namespace fogbench::drivers
