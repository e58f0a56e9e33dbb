// See modbus_server.hpp.
#include "modbus_server.hpp"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <spdlog/spdlog.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

namespace fogbench::mock {

ModbusServer::~ModbusServer() {
  close();
  if (ctx_ != nullptr) modbus_free(ctx_);
}

std::expected<void, std::string> ModbusServer::open(bool gateway, bool chamber) {
  ctx_ = modbus_new_tcp("127.0.0.1", 0);
  if (ctx_ == nullptr) return std::unexpected("libmodbus: " + std::string(modbus_strerror(errno)));
  // A request split across packets may wait this long for its rest; the response timeout is
  // only libmodbus's pause before flushing a malformed request. Both bound the loop's stalls.
  modbus_set_byte_timeout(ctx_, 0, 100000);
  modbus_set_response_timeout(ctx_, 0, 10000);

  if (!chamber) {
    listeners_.push_back({where_.thermistor_port, -1, {Device::thermistors}});
  } else if (listeners_.push_back({where_.chamber_port, -1, {Device::chamber}}); gateway) {
    listeners_[0].devices.push_back(Device::thermistors);
  } else {
    listeners_.push_back({where_.thermistor_port, -1, {Device::thermistors}});
  }
  for (auto& l : listeners_) {
    if (auto ok = open_listener(l); !ok) return ok;
  }
  return {};
}

std::expected<void, std::string> ModbusServer::open_listener(Listener& l) {
  modbus_t* ctx = modbus_new_tcp(where_.host.c_str(), l.port);
  if (ctx == nullptr) return std::unexpected("Modbus listener " + where_.host + ": " + modbus_strerror(errno));
  const int fd = modbus_tcp_listen(ctx, 16);
  const int err = errno;
  modbus_free(ctx);  // only the socket is kept: it is all the listener is
  if (fd < 0) {
    return std::unexpected("Modbus listener " + where_.host + ":" + std::to_string(l.port) + ": " + modbus_strerror(err));
  }
  if (l.port == 0) {
    sockaddr_in addr{};
    socklen_t len = sizeof addr;
    ::getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len);
    l.port = ntohs(addr.sin_port);  // kept, so a refused listener reopens on the same port
  }
  l.fd = fd;
  return {};
}

ModbusServer::Clock::time_point ModbusServer::watch(PollSet& set) {
  for (std::size_t i = 0; i < listeners_.size(); ++i) {
    const int fd = listeners_[i].fd;
    if (fd < 0) continue;
    set.add(fd, POLLIN, [this, i, fd](short) {
      if (listeners_[i].fd == fd) accept(i);  // not closed meanwhile by a refuse fault
    });
  }
  auto next_due = Clock::time_point::max();
  for (std::size_t i = 0; i < clients_.size(); ++i) {
    const auto& c = clients_[i];
    if (c.fd < 0) continue;
    if (c.pending) next_due = std::min(next_due, c.due);
    set.add(c.fd, c.pending ? 0 : POLLIN, [this, i, fd = c.fd](short revents) {
      auto& client = clients_[i];
      if (client.fd != fd) return;  // closed meanwhile (a drop fault)
      if (client.pending) {
        if (revents & (POLLHUP | POLLERR)) close_client(client, "hung up");
      } else {
        read_request(client);
      }
    });
  }
  return next_due;
}

void ModbusServer::after_round(Clock::time_point now) {
  for (auto& c : clients_) {
    if (c.fd >= 0 && c.pending && c.due <= now) {
      c.pending = false;
      reply(c, c.query.data(), c.query_length, c.device);
    }
  }
  std::erase_if(clients_, [](const Client& c) { return c.fd < 0; });
}

bool ModbusServer::refused(const Listener& l) const {
  return std::ranges::any_of(l.devices, [&](Device d) { return shared_.faults.refuse[static_cast<std::size_t>(d)]; });
}

void ModbusServer::update_listeners() {
  for (auto& l : listeners_) {
    bool refuse = false;
    {
      std::lock_guard lock(shared_.mutex);
      refuse = refused(l);
    }
    if (refuse && l.fd >= 0) {
      ::close(l.fd);  // connects now get ECONNREFUSED; clients already connected stay
      l.fd = -1;
    } else if (!refuse && l.fd < 0) {
      if (auto ok = open_listener(l); !ok) spdlog::error("reopening a refused listener: {}", ok.error());
    }
  }
}

void ModbusServer::drop_clients(std::optional<Device> device) {
  std::size_t n = 0;
  for (auto& c : clients_) {
    const auto& served = listeners_[c.listener].devices;
    if (c.fd >= 0 && (!device || std::ranges::find(served, *device) != served.end())) {
      ::close(c.fd);
      c.fd = -1;
      ++n;
    }
  }
  spdlog::info("dropped {} Modbus connection(s)", n);
}

std::size_t ModbusServer::open_clients() const {
  return static_cast<std::size_t>(std::ranges::count_if(clients_, [](const Client& c) { return c.fd >= 0; }));
}

void ModbusServer::accept(std::size_t li) {
  // Non-blocking: modbus_reply() sends while the register mutex is held, and a client that
  // never reads its replies must cost its connection (EAGAIN closes it), not the clock.
  // libmodbus waits in select() before each recv, so receiving is unaffected.
  const int fd = ::accept4(listeners_[li].fd, nullptr, nullptr, SOCK_CLOEXEC | SOCK_NONBLOCK);
  if (fd < 0) {
    if (errno != EAGAIN && errno != EINTR) spdlog::warn("Modbus accept: {}", std::strerror(errno));
    return;
  }
  const int one = 1;
  ::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
  Client c;
  c.fd = fd;
  c.listener = li;
  clients_.push_back(std::move(c));
  spdlog::debug("Modbus client connected on port {}", listeners_[li].port);
}

std::optional<Device> ModbusServer::device_for_unit(const Listener& l, int unit_id) const {
  if (unit_id == 255) return l.devices.front();  // "the device itself" on Modbus TCP
  for (Device d : l.devices) {
    const int id = d == Device::chamber ? where_.chamber_unit : where_.thermistor_unit;
    if (id == unit_id) return d;
  }
  return std::nullopt;
}

void ModbusServer::close_client(Client& c, const char* why) {
  spdlog::debug("Modbus client on port {} closed: {}", listeners_[c.listener].port, why);
  ::close(c.fd);
  c.fd = -1;
}

void ModbusServer::read_request(Client& c) {
  std::uint8_t query[MODBUS_TCP_MAX_ADU_LENGTH];
  modbus_set_socket(ctx_, c.fd);
  const int rc = modbus_receive(ctx_, query);
  if (rc < 0) {
    close_client(c, modbus_strerror(errno));
    return;
  }
  if (rc == 0) return;
  const int unit_id = query[modbus_get_header_length(ctx_) - 1];
  const auto device = device_for_unit(listeners_[c.listener], unit_id);
  if (!device) {
    // A gateway's answer for a unit it does not have: the client sees a protocol error.
    modbus_reply_exception(ctx_, query, MODBUS_EXCEPTION_GATEWAY_TARGET);
    return;
  }
  int stall_ms = 0;
  {
    std::lock_guard lock(shared_.mutex);
    stall_ms = shared_.faults.stall_ms[static_cast<std::size_t>(*device)];
  }
  if (stall_ms > 0) {
    c.pending = true;
    c.query.assign(query, query + rc);
    c.query_length = rc;
    c.device = *device;
    c.due = Clock::now() + std::chrono::milliseconds(stall_ms);
    return;
  }
  reply(c, query, rc, *device);
}

void ModbusServer::reply(Client& c, const std::uint8_t* query, int length, Device device) {
  modbus_set_socket(ctx_, c.fd);
  int rc = 0;
  {
    std::lock_guard lock(shared_.mutex);
    modbus_mapping_t* m = device == Device::chamber ? shared_.chamber->mapping() : shared_.thermistors->mapping();
    const int h = modbus_get_header_length(ctx_);
    const int function = query[h];
    const int address = (query[h + 1] << 8) | query[h + 2];
    const int count = function == 16 ? ((query[h + 3] << 8) | query[h + 4]) : 1;
    if (device == Device::chamber && shared_.faults.refuse_setpoint &&
        shared_.chamber->writes_setpoint(function, address, count)) {
      // The refuse_setpoint fault: the controller refuses the value as out of its range.
      rc = modbus_reply_exception(ctx_, query, MODBUS_EXCEPTION_ILLEGAL_DATA_VALUE);
    } else {
      rc = modbus_reply(ctx_, query, length, m);
    }
  }
  if (rc < 0) close_client(c, modbus_strerror(errno));
}

void ModbusServer::close() {
  for (auto& l : listeners_) {
    if (l.fd >= 0) ::close(l.fd);
    l.fd = -1;
  }
  for (auto& c : clients_) {
    if (c.fd >= 0) ::close(c.fd);
  }
  clients_.clear();
}

}  // namespace fogbench::mock
