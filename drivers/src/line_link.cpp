// Line exchanges with an ASCII controller over TCP or a serial port: deadlines from poll(),
// link failures closing the link under backoff, messages that show the half line at a timeout.
#include "fogbench/drivers/line_link.hpp"

#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "fogbench/drivers/chamber_dialects.hpp"
#include "termios_baud.hpp"

namespace fogbench::drivers {

namespace {

using SteadyClock = std::chrono::steady_clock;

int ms_until(SteadyClock::time_point deadline) {
  const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - SteadyClock::now()).count();
  return left <= 0 ? 0 : static_cast<int>(left);
}

}  // namespace

std::string LineEndpoint::describe() const {
  if (transport == Transport::tcp) return "tcp " + host + ":" + std::to_string(port);
  return "serial " + device + " " + std::to_string(baud) + " " + std::to_string(data_bits) + parity +
         std::to_string(stop_bits);
}

LineLink::LineLink(LineEndpoint endpoint, std::string name, std::string line_end, char terminator, Clock clock)
    : endpoint_(std::move(endpoint)),
      name_(std::move(name)),
      line_end_(std::move(line_end)),
      terminator_(terminator),
      clock_(clock ? std::move(clock) : Clock([] { return SteadyClock::now(); })),
      backoff_(endpoint_.backoff) {}

LineLink::~LineLink() { disconnect(); }

void LineLink::disconnect() noexcept {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
  pending_.clear();
}

std::string LineLink::prefix() const { return name_ + " (" + endpoint_.describe() + ")"; }

std::unexpected<DriverError> LineLink::link_failed(ErrorCode code, std::string message) {
  disconnect();
  backoff_.record_failure(clock_());
  return fail(code, prefix() + ": " + std::move(message));
}

Result<void> LineLink::open_tcp(SteadyClock::time_point deadline) {
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  addrinfo* found = nullptr;
  const std::string port = std::to_string(endpoint_.port);
  if (int rc = ::getaddrinfo(endpoint_.host.c_str(), port.c_str(), &hints, &found); rc != 0) {
    return link_failed(ErrorCode::connection, std::string("connect: ") + ::gai_strerror(rc));
  }
  std::string last = "no address";
  ErrorCode last_code = ErrorCode::connection;
  for (addrinfo* a = found; a != nullptr; a = a->ai_next) {
    int fd = ::socket(a->ai_family, a->ai_socktype | SOCK_NONBLOCK | SOCK_CLOEXEC, a->ai_protocol);
    if (fd < 0) {
      last = std::strerror(errno);
      continue;
    }
    int rc = ::connect(fd, a->ai_addr, a->ai_addrlen);
    if (rc != 0 && errno == EINPROGRESS) {
      pollfd p{fd, POLLOUT, 0};
      int n = 0;
      do n = ::poll(&p, 1, ms_until(deadline));
      while (n < 0 && errno == EINTR);
      if (n == 0) {
        ::close(fd);
        last = "connect: no answer within " + std::to_string(endpoint_.response_timeout_ms) + " ms";
        last_code = ErrorCode::timeout;
        continue;
      }
      int err = 0;
      socklen_t len = sizeof err;
      ::getsockopt(fd, SOL_SOCKET, SO_ERROR, &err, &len);
      rc = err == 0 ? 0 : -1;
      errno = err;
    }
    if (rc != 0) {
      last = std::string("connect: ") + std::strerror(errno);
      last_code = ErrorCode::connection;
      ::close(fd);
      continue;
    }
    int one = 1;
    ::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
    fd_ = fd;
    break;
  }
  ::freeaddrinfo(found);
  if (fd_ < 0) return link_failed(last_code, last);
  return {};
}

Result<void> LineLink::open_serial() {
  int fd = ::open(endpoint_.device.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) return link_failed(ErrorCode::connection, "open: " + std::string(std::strerror(errno)));
  termios t{};
  if (::tcgetattr(fd, &t) != 0) {
    const std::string why = std::strerror(errno);
    ::close(fd);
    return link_failed(ErrorCode::io, "tcgetattr: " + why);
  }
  ::cfmakeraw(&t);
  const auto speed = detail::termios_baud(endpoint_.baud);
  if (!speed) {
    ::close(fd);
    return link_failed(ErrorCode::config, "baud " + std::to_string(endpoint_.baud) + " not supported");
  }
  ::cfsetispeed(&t, *speed);
  ::cfsetospeed(&t, *speed);
  t.c_cflag &= ~(CSIZE | PARENB | PARODD | CSTOPB);
  t.c_cflag |= (endpoint_.data_bits == 7 ? CS7 : CS8) | CLOCAL | CREAD;
  if (endpoint_.parity == 'E') t.c_cflag |= PARENB;
  if (endpoint_.parity == 'O') t.c_cflag |= PARENB | PARODD;
  if (endpoint_.stop_bits == 2) t.c_cflag |= CSTOPB;
  if (::tcsetattr(fd, TCSANOW, &t) != 0) {
    const std::string why = std::strerror(errno);
    ::close(fd);
    return link_failed(ErrorCode::io, "tcsetattr: " + why);
  }
  ::tcflush(fd, TCIOFLUSH);
  fd_ = fd;
  return {};
}

Result<void> LineLink::connect() {
  if (fd_ >= 0) return {};
  const auto now = clock_();
  if (!backoff_.may_attempt(now)) {
    return fail(ErrorCode::connection,
                prefix() + ": waiting " + std::to_string(backoff_.remaining(now).count()) +
                    " ms before the next connection attempt (" +
                    std::to_string(backoff_.consecutive_failures()) + " consecutive failures)");
  }
  const auto deadline = SteadyClock::now() + std::chrono::milliseconds(endpoint_.response_timeout_ms);
  auto ok = endpoint_.transport == LineEndpoint::Transport::tcp ? open_tcp(deadline) : open_serial();
  if (!ok) return ok;
  backoff_.record_success();
  return {};
}

Result<std::string> LineLink::exchange(std::string_view command, std::string_view shown) {
  if (auto ok = connect(); !ok) return std::unexpected(ok.error());
  const std::string what = "'" + std::string(shown) + "'";
  const auto deadline = SteadyClock::now() + std::chrono::milliseconds(endpoint_.response_timeout_ms);
  // Whatever came after the last reply (a LF after a CR terminator, a stray line) is not this
  // command's answer.
  pending_.clear();
  std::string out(command);
  out += line_end_;
  std::size_t sent = 0;
  while (sent < out.size()) {
    // MSG_NOSIGNAL: a peer that closed is an error value here, not a SIGPIPE for the process.
    ssize_t n = endpoint_.transport == LineEndpoint::Transport::tcp
                    ? ::send(fd_, out.data() + sent, out.size() - sent, MSG_NOSIGNAL)
                    : ::write(fd_, out.data() + sent, out.size() - sent);
    if (n > 0) {
      sent += static_cast<std::size_t>(n);
      continue;
    }
    if (n < 0 && errno == EINTR) continue;
    if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
      pollfd p{fd_, POLLOUT, 0};
      if (::poll(&p, 1, ms_until(deadline)) == 0) {
        return link_failed(ErrorCode::timeout, what + ": could not send within " +
                                                   std::to_string(endpoint_.response_timeout_ms) + " ms");
      }
      continue;
    }
    return link_failed(ErrorCode::connection, what + ": send: " + std::strerror(errno));
  }
  std::string line;
  while (true) {
    // Strip CR and LF ahead of a reply (the LF of a CR LF whose CR ended the last one).
    std::size_t lead = 0;
    while (lead < pending_.size() && (pending_[lead] == '\r' || pending_[lead] == '\n') &&
           pending_[lead] != terminator_) {
      ++lead;
    }
    if (lead > 0 && lead < pending_.size()) pending_.erase(0, lead);
    if (auto at = pending_.find(terminator_); at != std::string::npos) {
      line = pending_.substr(0, at);
      pending_.erase(0, at + 1);
      while (!line.empty() && (line.front() == '\r' || line.front() == '\n')) line.erase(0, 1);
      while (!line.empty() && (line.back() == '\r' || line.back() == '\n')) line.pop_back();
      if (line.empty()) continue;  // a bare line end: the reply is still to come
      return line;
    }
    pollfd p{fd_, POLLIN, 0};
    int n = ::poll(&p, 1, ms_until(deadline));
    if (n < 0 && errno == EINTR) continue;
    if (n == 0) {
      std::string got = pending_.empty() ? "nothing" : "a half line '" + printable(pending_) + "'";
      return link_failed(ErrorCode::timeout, what + ": no whole reply within " +
                                                 std::to_string(endpoint_.response_timeout_ms) +
                                                 " ms (received " + got + ")");
    }
    char buf[512];
    ssize_t r = ::read(fd_, buf, sizeof buf);
    if (r > 0) {
      pending_.append(buf, static_cast<std::size_t>(r));
      if (pending_.size() > 4096) {
        return link_failed(ErrorCode::protocol, what + ": a reply of over 4096 bytes without a line end ('" +
                                                    printable(pending_.substr(0, 64)) + "...')");
      }
      continue;
    }
    if (r < 0 && (errno == EINTR || errno == EAGAIN || errno == EWOULDBLOCK)) continue;
    std::string why = r == 0 ? "the peer closed the connection" : std::string("read: ") + std::strerror(errno);
    if (!pending_.empty()) why += " after a half line '" + printable(pending_) + "'";
    return link_failed(ErrorCode::connection, what + ": " + why);
  }
}

}  // namespace fogbench::drivers
