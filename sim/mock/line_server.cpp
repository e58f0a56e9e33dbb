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

namespace fogbench::mock {

std::expected<void, std::string> LineServer::open() {
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
  clients_.push_back({fd, {}, {}});
}

void LineServer::close_client(Client& c) {
  if (c.fd >= 0) ::close(c.fd);
  c.fd = -1;
}

void LineServer::send(Client& c, const std::string& reply) {
  if (::send(c.fd, reply.data(), reply.size(), MSG_NOSIGNAL) != static_cast<ssize_t>(reply.size())) close_client(c);
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
  // Espec and the rate table end a line in CR LF, SIMSERV in CR: a CR or an LF ends one.
  while (c.fd >= 0) {
    const auto at = c.in.find_first_of("\r\n");
    if (at == std::string::npos) break;
    std::string line = c.in.substr(0, at);
    c.in.erase(0, at + 1);
    if (line.empty()) continue;
    Reply reply = answer_(line);
    spdlog::debug("{}: '{}' -> '{}'", name_, drivers::printable(line), drivers::printable(reply.text));
    if (reply.stall_ms > 0 || !c.replies.empty()) {
      c.replies.emplace_back(Clock::now() + std::chrono::milliseconds(reply.stall_ms), std::move(reply.text));
    } else {
      send(c, reply.text);
    }
  }
  if (c.fd >= 0 && c.in.size() > 4096) close_client(c);
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
    set.add(c.fd, POLLIN, [this, i, fd = c.fd](short) {
      if (i < clients_.size() && clients_[i].fd == fd) read(clients_[i]);
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

void LineServer::drop_clients() {
  for (auto& c : clients_) close_client(c);
}

std::size_t LineServer::open_clients() const {
  return static_cast<std::size_t>(std::ranges::count_if(clients_, [](const Client& c) { return c.fd >= 0; }));
}

void LineServer::close() {
  drop_clients();
  clients_.clear();
  if (listen_fd_ >= 0) ::close(listen_fd_);
  listen_fd_ = -1;
}

}  // namespace fogbench::mock
