// Transport selection from a configuration string, and the datagram read loop shared by the
// SocketCAN and unix transports.
#include "fogbench/drivers/can_transport.hpp"

#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cctype>
#include <charconv>
#include <cstring>

#include "datagram_reader.hpp"

namespace fogbench::drivers {

Result<TransportSpec> parse_transport_spec(std::string_view spec) {
  const auto bad = [&](const std::string& why) {
    return fail(ErrorCode::config,
                "gyro_bus.transport: " + why + " in '" + std::string(spec) +
                    "' (expected can:IFACE, unix:PATH, replay:FILE[?speed=N] or serial:DEVICE[?baud=N][&framing=8N1])");
  };
  const auto colon = spec.find(':');
  if (colon == std::string_view::npos) return bad("no transport kind");
  const auto kind = spec.substr(0, colon);
  std::string_view target = spec.substr(colon + 1);
  TransportSpec out;
  if (kind == "can") {
    out.kind = TransportSpec::Kind::socketcan;
    if (target.empty() || target.size() >= 16) return bad("an interface name of 1..15 characters");
  } else if (kind == "unix") {
    out.kind = TransportSpec::Kind::unix_seqpacket;
    // sockaddr_un.sun_path holds 108 bytes including the terminating zero.
    if (target.empty() || target.size() >= 108) return bad("a socket path of 1..107 characters");
  } else if (kind == "replay") {
    out.kind = TransportSpec::Kind::replay;
    if (const auto q = target.find('?'); q != std::string_view::npos) {
      const auto option = target.substr(q + 1);
      target = target.substr(0, q);
      if (!option.starts_with("speed=")) return bad("unknown replay option");
      const auto num = option.substr(6);
      double speed = -1;
      auto [end, ec] = std::from_chars(num.data(), num.data() + num.size(), speed);
      if (ec != std::errc{} || end != num.data() + num.size() || speed < 0 || speed > 1e6) {
        return bad("a replay speed 0..1e6");
      }
      out.speed = speed;
    }
    if (target.empty()) return bad("no log file");
  } else if (kind == "serial") {
    out.kind = TransportSpec::Kind::serial;
    if (const auto q = target.find('?'); q != std::string_view::npos) {
      std::string_view options = target.substr(q + 1);
      target = target.substr(0, q);
      bool have_baud = false, have_framing = false;
      while (true) {
        const auto amp = options.find('&');
        const auto option = options.substr(0, amp);
        if (option.starts_with("baud=")) {
          if (have_baud) return bad("baud given twice");
          have_baud = true;
          const auto num = option.substr(5);
          int baud = 0;
          auto [end, ec] = std::from_chars(num.data(), num.data() + num.size(), baud);
          if (ec != std::errc{} || end != num.data() + num.size() || !serial_baud_supported(baud)) {
            return bad("a baud rate of 1200..4000000 that termios knows (e.g. 115200, 460800, 921600)");
          }
          out.baud = baud;
        } else if (option.starts_with("framing=")) {
          if (have_framing) return bad("framing given twice");
          have_framing = true;
          auto framing = parse_serial_framing(option.substr(8), "gyro_bus.transport: framing");
          if (!framing) {
            return fail(ErrorCode::config, framing.error().message + " in '" + std::string(spec) + "'");
          }
          out.framing = *framing;
        } else {
          return bad("unknown serial option '" + std::string(option) + "' (baud=N, framing=8N1)");
        }
        if (amp == std::string_view::npos) break;
        options = options.substr(amp + 1);
      }
    }
    if (target.empty()) return bad("no serial device");
  } else {
    return bad("unknown transport kind '" + std::string(kind) + "'");
  }
  out.target = std::string(target);
  return out;
}

std::string SerialFraming::to_string() const {
  return std::to_string(data_bits) + parity + std::to_string(stop_bits);
}

Result<SerialFraming> parse_serial_framing(std::string_view text, const std::string& field) {
  const auto bad = [&](const std::string& why) {
    return fail(ErrorCode::config, field + ": '" + std::string(text) + "': " + why +
                                       " (expected data bits, parity, stop bits: 8N1, 8E1, 8O1, 7E1, 8N2, ...)");
  };
  if (text.size() != 3) return bad("expected 3 characters");
  SerialFraming f;
  if (text[0] != '7' && text[0] != '8') return bad("data bits '" + std::string(1, text[0]) + "' is not 7 or 8");
  f.data_bits = text[0] - '0';
  const char p = static_cast<char>(std::toupper(static_cast<unsigned char>(text[1])));
  if (p != 'N' && p != 'E' && p != 'O') {
    return bad("parity '" + std::string(1, text[1]) + "' is not N (none), E (even) or O (odd)");
  }
  f.parity = p;
  if (text[2] != '1' && text[2] != '2') return bad("stop bits '" + std::string(1, text[2]) + "' is not 1 or 2");
  f.stop_bits = text[2] - '0';
  return f;
}

Result<std::unique_ptr<CanTransport>> open_transport(const TransportSpec& spec,
                                                     std::span<const std::uint16_t> node_ids,
                                                     MonotonicClock clock) {
  switch (spec.kind) {
    case TransportSpec::Kind::socketcan: return open_socketcan(spec.target, node_ids);
    case TransportSpec::Kind::unix_seqpacket: return open_unix_seqpacket(spec.target);
    case TransportSpec::Kind::replay: return open_replay(spec.target, spec.speed, std::move(clock));
    case TransportSpec::Kind::serial:
      return fail(ErrorCode::config, "serial:" + spec.target +
                                         ": a serial gyro needs its frame format and unit (GyroBus::open, open_serial_gyro)");
  }
  return fail(ErrorCode::config, "unknown transport");
}

namespace detail {

Result<std::size_t> read_frame_datagrams(int fd, std::vector<::can_frame>& out,
                                         std::uint64_t& malformed, const char* what,
                                         std::size_t max_frames) {
  constexpr unsigned batch = 64;
  ::can_frame frames[batch];
  iovec iov[batch];
  mmsghdr msgs[batch];
  std::size_t got = 0;
  while (got < max_frames) {
    std::memset(msgs, 0, sizeof msgs);
    for (unsigned i = 0; i < batch; ++i) {
      iov[i] = {&frames[i], sizeof(::can_frame)};
      msgs[i].msg_hdr.msg_iov = &iov[i];
      msgs[i].msg_hdr.msg_iovlen = 1;
    }
    const int n = ::recvmmsg(fd, msgs, batch, MSG_DONTWAIT, nullptr);
    if (n < 0) {
      if (errno == EAGAIN || errno == EWOULDBLOCK) break;
      if (errno == EINTR) continue;
      const int err = errno;
      if (got > 0) break;  // hand over what arrived; the error repeats on the next call
      return fail(err == ENETDOWN || err == ECONNRESET || err == ENOTCONN || err == ENODEV
                      ? ErrorCode::connection
                      : ErrorCode::io,
                  std::string(what) + ": receive: " + std::strerror(err));
    }
    for (int i = 0; i < n; ++i) {
      const auto len = msgs[i].msg_len;
      if (len == 0) {
        if (got > 0) return got;
        return fail(ErrorCode::connection, std::string(what) + ": peer closed the connection");
      }
      if (len != sizeof(::can_frame) || (msgs[i].msg_hdr.msg_flags & MSG_TRUNC)) {
        ++malformed;
        continue;
      }
      out.push_back(frames[i]);
      ++got;
    }
    if (static_cast<unsigned>(n) < batch) break;
  }
  return got;
}

DatagramTransport::DatagramTransport(int fd, std::string name) : fd_(fd), name_(std::move(name)) {}
DatagramTransport::~DatagramTransport() { ::close(fd_); }

Result<std::size_t> DatagramTransport::read(std::vector<::can_frame>& out) {
  return read_frame_datagrams(fd_, out, malformed_, name_.c_str());
}

}  // namespace detail
}  // namespace fogbench::drivers
