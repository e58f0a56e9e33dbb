// See ascii_chamber.hpp.
#include "ascii_chamber.hpp"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <spdlog/spdlog.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>

#include "fogbench/drivers/chamber_dialects.hpp"

namespace fogbench::mock {

namespace espec = drivers::espec;
namespace simserv = drivers::simserv;

namespace {

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\r' || s.front() == '\n')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\r' || s.back() == '\n')) s.remove_suffix(1);
  return s;
}

std::optional<double> number(std::string_view s) {
  s = trim(s);
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  double v = 0;
  auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (s.empty() || ec != std::errc{} || end != s.data() + s.size() || !std::isfinite(v)) return std::nullopt;
  return v;
}

bool settable(double c) { return c >= ascii_setpoint_min_c && c <= ascii_setpoint_max_c; }

std::string espec_line(std::string text) { return text + std::string(espec::line_end); }

}  // namespace

std::optional<ChamberDialect> parse_chamber_dialect(std::string_view name) noexcept {
  if (name == "modbus") return ChamberDialect::modbus;
  if (name == "espec") return ChamberDialect::espec;
  if (name == "simserv") return ChamberDialect::simserv;
  return std::nullopt;
}

std::string_view to_string(ChamberDialect dialect) noexcept {
  switch (dialect) {
    case ChamberDialect::modbus: return "modbus";
    case ChamberDialect::espec: return "espec";
    case ChamberDialect::simserv: return "simserv";
  }
  return "?";
}

std::string answer_espec(std::string_view line, ChamberRegisters& chamber, bool refuse_setpoint) {
  line = trim(line);
  const double sp = chamber.setpoint_c(0.0);
  if (line == espec::cmd_type) return espec_line("T,P300,250.0");
  if (line == espec::cmd_temp) {
    return espec_line(simserv::format_value(chamber.process_value_c()) + "," + simserv::format_value(sp) + "," +
                      simserv::format_value(ascii_setpoint_max_c) + "," + simserv::format_value(ascii_setpoint_min_c));
  }
  const std::string mode = chamber.running() ? "CONSTANT" : "STANDBY";
  if (line == espec::cmd_mode) return espec_line(mode);
  if (line == espec::cmd_mon) {
    return espec_line(simserv::format_value(chamber.process_value_c()) + ",," + mode + "," +
                      (chamber.alarm() ? "1" : "0"));
  }
  if (line == espec::cmd_alarm) return espec_line(chamber.alarm() ? "1,1" : "0");
  // Settings: "TEMP, S20.0" and "MODE, CONSTANT"; the controller takes them with or without the
  // space after the comma.
  auto setting = [&](std::string_view name) -> std::optional<std::string_view> {
    if (!line.starts_with(name) || line.size() <= name.size() || line[name.size()] != ',') return std::nullopt;
    return trim(line.substr(name.size() + 1));
  };
  if (auto arg = setting("TEMP")) {
    if (arg->empty() || arg->front() != 'S') return espec_line("NA:PARA ERR");
    auto c = number(arg->substr(1));
    if (!c) return espec_line("NA:PARA ERR");
    if (refuse_setpoint || !settable(*c)) return espec_line("NA:DATA OUT OF RANGE");
    chamber.write_setpoint_c(*c);
    return espec_line("OK:TEMP,S" + simserv::format_value(*c));
  }
  if (auto arg = setting("MODE")) {
    if (*arg == "CONSTANT") {
      chamber.write_running(true);
    } else if (*arg == "STANDBY" || *arg == "OFF") {
      chamber.write_running(false);
    } else {
      return espec_line("NA:PARA ERR");
    }
    return espec_line("OK:MODE," + std::string(*arg));
  }
  return espec_line("NA:CMD ERR");
}

std::string answer_simserv(std::string_view line, ChamberRegisters& chamber, bool refuse_setpoint) {
  auto reply = [](int code, std::vector<std::string> values = {}) { return simserv::format_reply(code, values); };
  auto cmd = simserv::parse_command(trim(line));
  if (!cmd) return reply(simserv::err_unknown_command);
  if (cmd->chamber_index != 1) return reply(simserv::err_bad_parameters);
  const auto& a = cmd->args;
  const bool temp_var = !a.empty() && a[0] == std::to_string(simserv::temperature_variable);
  switch (cmd->number) {
    case simserv::cmd_get_info:
      return reply(simserv::ok, {"fogbench mock SIMSERV"});
    case simserv::cmd_get_value:
      if (a.size() != 1 || !temp_var) return reply(simserv::err_bad_parameters);
      return reply(simserv::ok, {simserv::format_value(chamber.process_value_c())});
    case simserv::cmd_get_setpoint:
      if (a.size() != 1 || !temp_var) return reply(simserv::err_bad_parameters);
      return reply(simserv::ok, {simserv::format_value(chamber.setpoint_c(0.0))});
    case simserv::cmd_set_setpoint: {
      if (a.size() != 2 || !temp_var) return reply(simserv::err_bad_parameters);
      auto c = number(a[1]);
      if (!c || refuse_setpoint || !settable(*c)) return reply(simserv::err_bad_parameters);
      chamber.write_setpoint_c(*c);
      return reply(simserv::ok);
    }
    case simserv::cmd_start_manual:
      if (a.size() != 2 || a[0] != "1" || (a[1] != "0" && a[1] != "1")) return reply(simserv::err_bad_parameters);
      chamber.write_running(a[1] == "1");
      return reply(simserv::ok);
    case simserv::cmd_get_status: {
      unsigned status = 1;
      if (chamber.running()) status |= simserv::status_running_bit;
      if (chamber.alarm()) status |= simserv::status_alarm_bit;
      return reply(simserv::ok, {std::to_string(status)});
    }
    default:
      return reply(simserv::err_unknown_command);
  }
}

// ---- the listener --------------------------------------------------------------------------

std::expected<void, std::string> AsciiChamberServer::open() {
  const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
  if (fd < 0) return std::unexpected(std::string("socket: ") + std::strerror(errno));
  int one = 1;
  ::setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<std::uint16_t>(port_));
  if (::inet_pton(AF_INET, host_.c_str(), &addr.sin_addr) != 1) {
    ::close(fd);
    return std::unexpected("chamber listener: '" + host_ + "' is not an IPv4 address");
  }
  if (::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0 || ::listen(fd, 16) != 0) {
    const std::string why = std::strerror(errno);
    ::close(fd);
    return std::unexpected("chamber listener " + host_ + ":" + std::to_string(port_) + ": " + why);
  }
  if (port_ == 0) {
    socklen_t len = sizeof addr;
    ::getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len);
    port_ = ntohs(addr.sin_port);  // kept, so a refused listener reopens on the same port
  }
  listen_fd_ = fd;
  return {};
}

void AsciiChamberServer::update_listener() {
  bool refuse = false;
  {
    std::lock_guard lock(shared_.mutex);
    refuse = shared_.faults.refuse[static_cast<std::size_t>(Device::chamber)];
  }
  if (refuse && listen_fd_ >= 0) {
    ::close(listen_fd_);
    listen_fd_ = -1;
  } else if (!refuse && listen_fd_ < 0) {
    if (auto ok = open(); !ok) spdlog::error("reopening the refused chamber listener: {}", ok.error());
  }
}

void AsciiChamberServer::accept() {
  const int fd = ::accept4(listen_fd_, nullptr, nullptr, SOCK_CLOEXEC | SOCK_NONBLOCK);
  if (fd < 0) return;
  int one = 1;
  ::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
  spdlog::debug("{} chamber client connected", to_string(dialect_));
  clients_.push_back({fd, {}, {}});
}

void AsciiChamberServer::send(Client& c, const std::string& reply) {
  if (::send(c.fd, reply.data(), reply.size(), MSG_NOSIGNAL) != static_cast<ssize_t>(reply.size())) {
    ::close(c.fd);
    c.fd = -1;
  }
}

void AsciiChamberServer::read(Client& c) {
  char buf[1024];
  const auto n = ::recv(c.fd, buf, sizeof buf, 0);
  if (n == 0 || (n < 0 && errno != EAGAIN && errno != EINTR)) {
    ::close(c.fd);
    c.fd = -1;
    return;
  }
  if (n < 0) return;
  c.in.append(buf, static_cast<std::size_t>(n));
  // Espec commands end in CR LF, SIMSERV's in CR: a CR ends a command in both.
  while (c.fd >= 0) {
    const auto at = c.in.find_first_of("\r\n");
    if (at == std::string::npos) break;
    std::string line = c.in.substr(0, at);
    c.in.erase(0, at + 1);
    if (line.empty()) continue;
    std::string reply;
    int stall_ms = 0;
    {
      std::lock_guard lock(shared_.mutex);
      const bool refuse = shared_.faults.refuse_setpoint;
      reply = dialect_ == ChamberDialect::espec ? answer_espec(line, *shared_.chamber, refuse)
                                                : answer_simserv(line, *shared_.chamber, refuse);
      stall_ms = shared_.faults.stall_ms[static_cast<std::size_t>(Device::chamber)];
    }
    spdlog::debug("{} chamber: '{}' -> '{}'", to_string(dialect_), drivers::printable(line), drivers::printable(reply));
    if (stall_ms > 0 || !c.replies.empty()) {
      c.replies.emplace_back(Clock::now() + std::chrono::milliseconds(stall_ms), std::move(reply));
    } else {
      send(c, reply);
    }
  }
  if (c.fd >= 0 && c.in.size() > 4096) {
    ::close(c.fd);
    c.fd = -1;
  }
}

AsciiChamberServer::Clock::time_point AsciiChamberServer::watch(PollSet& set) {
  if (listen_fd_ >= 0) {
    set.add(listen_fd_, POLLIN, [this, fd = listen_fd_](short) {
      if (listen_fd_ == fd) accept();
    });
  }
  auto next_due = Clock::time_point::max();
  for (std::size_t i = 0; i < clients_.size(); ++i) {
    const auto& c = clients_[i];
    if (c.fd < 0) continue;
    if (!c.replies.empty()) next_due = std::min(next_due, c.replies.front().first);
    set.add(c.fd, POLLIN, [this, i, fd = c.fd](short) {
      if (clients_[i].fd == fd) read(clients_[i]);
    });
  }
  return next_due;
}

void AsciiChamberServer::after_round(Clock::time_point now) {
  for (auto& c : clients_) {
    while (c.fd >= 0 && !c.replies.empty() && c.replies.front().first <= now) {
      send(c, c.replies.front().second);
      c.replies.erase(c.replies.begin());
    }
  }
  std::erase_if(clients_, [](const Client& c) { return c.fd < 0; });
}

void AsciiChamberServer::drop_clients() {
  for (auto& c : clients_) {
    if (c.fd >= 0) ::close(c.fd);
    c.fd = -1;
  }
}

std::size_t AsciiChamberServer::open_clients() const {
  return static_cast<std::size_t>(std::ranges::count_if(clients_, [](const Client& c) { return c.fd >= 0; }));
}

void AsciiChamberServer::close() {
  drop_clients();
  clients_.clear();
  if (listen_fd_ >= 0) ::close(listen_fd_);
  listen_fd_ = -1;
}

}  // namespace fogbench::mock
