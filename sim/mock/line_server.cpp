// See line_server.hpp.
#include "line_server.hpp"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <spdlog/spdlog.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

#include "fogbench/drivers/chamber_dialects.hpp"
#include "unix_socket.hpp"

namespace fogbench::mock {

std::expected<void, std::string> LineServer::open() {
  if (!unix_path_.empty()) {
    auto fd = listen_unix(unix_path_, SOCK_STREAM);
    if (!fd) return std::unexpected(fd.error());
    listen_fd_ = *fd;
    return {};
  }
  const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
  if (fd < 0) return std::unexpected(std::string("socket: ") + std::strerror(errno));
  int one = 1;
  ::setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<std::uint16_t>(port_));
  if (::inet_pton(AF_INET, host_.c_str(), &addr.sin_addr) != 1) {
    ::close(fd);
    return std::unexpected(name_ + " listener: '" + host_ + "' is not an IPv4 address");
  }
  if (::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0 || ::listen(fd, 16) != 0) {
    const std::string why = std::strerror(errno);
    ::close(fd);
    return std::unexpected(name_ + " listener " + host_ + ":" + std::to_string(port_) + ": " + why);
  }
  if (port_ == 0) {
    socklen_t len = sizeof addr;
    ::getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len);
    port_ = ntohs(addr.sin_port);
  }
  listen_fd_ = fd;
  return {};
}

void LineServer::refuse(bool on) {
  if (!unix_path_.empty()) return;  // TCP listeners only
  if (on && listen_fd_ >= 0) {
    ::close(listen_fd_);
    listen_fd_ = -1;
  } else if (!on && listen_fd_ < 0) {
    if (auto ok = open(); !ok) spdlog::error("reopening the refused {} listener: {}", name_, ok.error());
  }
}

void LineServer::accept() {
  const int fd = ::accept4(listen_fd_, nullptr, nullptr, SOCK_CLOEXEC | SOCK_NONBLOCK);
  if (fd < 0) return;
  int one = 1;
  ::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
  spdlog::debug("{} client connected", name_);
  clients_.push_back({fd, {}, {}, {}});
}

void LineServer::close_client(Client& c) {
  if (c.fd >= 0) ::close(c.fd);
  c.fd = -1;
}

void LineServer::write_out(Client& c) {
  while (c.fd >= 0 && !c.out.empty()) {
    const auto n = ::send(c.fd, c.out.data(), c.out.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
    if (n < 0) {
      if (errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR) close_client(c);
      return;
    }
    c.out.erase(0, static_cast<std::size_t>(n));
  }
}

void LineServer::send(Client& c, const std::string& reply) {
  c.out += reply;
  write_out(c);
  if (c.out.size() > max_unsent_bytes) {
    spdlog::warn("{}: a client left {} bytes of replies unread: closed", name_, c.out.size());
    close_client(c);
  }
}

void LineServer::read(Client& c) {
  char buf[1024];
  const auto n = ::recv(c.fd, buf, sizeof buf, 0);
  if (n == 0 || (n < 0 && errno != EAGAIN && errno != EINTR)) {
    close_client(c);
    return;
  }
  if (n < 0) return;
  c.in.append(buf, static_cast<std::size_t>(n));
  // Espec and the rate table end a line in CR LF, SIMSERV in CR: a CR or an LF ends one. The
  // control socket's JSON lines end in LF (a CR before it dropped).
  while (c.fd >= 0) {
    const auto at = options_.lf_only ? c.in.find('\n') : c.in.find_first_of("\r\n");
    if (at == std::string::npos) break;
    std::string line = c.in.substr(0, at);
    c.in.erase(0, at + 1);
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty()) continue;
    Reply reply = answer_(line);
    spdlog::debug("{}: '{}' -> '{}'", name_, drivers::printable(line), drivers::printable(reply.text));
    if (reply.stall_ms > 0 || !c.replies.empty()) {
      c.replies.emplace_back(Clock::now() + std::chrono::milliseconds(reply.stall_ms), std::move(reply.text));
    } else {
      send(c, reply.text);
    }
  }
  if (c.fd >= 0 && c.in.size() > max_line_bytes) {
    spdlog::warn("{}: a client sent more than {} bytes without a line end: closed", name_, max_line_bytes);
    if (!options_.overflow_reply.empty()) {
      c.out += options_.overflow_reply;
      write_out(c);
    }
    close_client(c);
  }
}

LineServer::Clock::time_point LineServer::watch(PollSet& set) {
  std::erase_if(clients_, [](const Client& c) { return c.fd < 0; });
  if (listen_fd_ >= 0) {
    set.add(listen_fd_, POLLIN, [this, fd = listen_fd_](short) {
      if (listen_fd_ == fd) accept();
    });
  }
  auto next_due = Clock::time_point::max();
  for (std::size_t i = 0; i < clients_.size(); ++i) {
    const auto& c = clients_[i];
    if (!c.replies.empty()) next_due = std::min(next_due, c.replies.front().first);
    const auto events = static_cast<short>(POLLIN | (c.out.empty() ? 0 : POLLOUT));
    set.add(c.fd, events, [this, i, fd = c.fd](short revents) {
      if (i >= clients_.size() || clients_[i].fd != fd) return;
      if (revents & POLLOUT) write_out(clients_[i]);
      if (clients_[i].fd >= 0 && (revents & ~POLLOUT) != 0) read(clients_[i]);
    });
  }
  return next_due;
}

void LineServer::after_round(Clock::time_point now) {
  for (auto& c : clients_) {
    while (c.fd >= 0 && !c.replies.empty() && c.replies.front().first <= now) {
      send(c, c.replies.front().second);
      c.replies.erase(c.replies.begin());
    }
  }
  std::erase_if(clients_, [](const Client& c) { return c.fd < 0; });
}

void LineServer::flush() {
  for (auto& c : clients_) write_out(c);
}

void LineServer::drop_clients() {
  for (auto& c : clients_) close_client(c);
}

std::size_t LineServer::open_clients() const {
  return static_cast<std::size_t>(std::ranges::count_if(clients_, [](const Client& c) { return c.fd >= 0; }));
}

void LineServer::close() {
  drop_clients();
  clients_.clear();
  if (listen_fd_ >= 0) {
    ::close(listen_fd_);
    if (!unix_path_.empty()) ::unlink(unix_path_.c_str());
  }
  listen_fd_ = -1;
}

}  // namespace fogbench::mock
