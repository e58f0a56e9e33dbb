// fogctl's daemon client: a blocking connection to fogbenchd's command socket (newline-delimited
// JSON, docs/protocol.md, read with fogbench::protocol's framing and limits), and a run's samples
// fetched as a RunData. Plain blocking POSIX sockets with poll() deadlines: a command-line tool
// waits for one thing at a time. The commands are in client_commands.cpp, watching in watch.cpp.
#include "client.hpp"

#include <fcntl.h>
#include <netdb.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>

#include "fogbench/protocol/framing.hpp"
#include "fogbench/protocol/protocol.hpp"
#include "fogbench/storage/run_data.hpp"

namespace fogbench::cli {

using nlohmann::json;
using SteadyClock = std::chrono::steady_clock;

std::string default_socket() {
  const char* env = std::getenv("FOGBENCH_SOCKET");
  return env && *env ? env : "/run/fogbench/fogbenchd.sock";
}

std::string default_token() {
  const char* env = std::getenv("FOGBENCH_TOKEN");
  return env ? env : "";
}

std::string_view to_string(ClientErrc c) {
  switch (c) {
    case ClientErrc::reply: return "reply";
    case ClientErrc::connection: return "connection";
    case ClientErrc::timeout: return "timeout";
    case ClientErrc::protocol: return "protocol";
    case ClientErrc::bad_option: return "bad_option";
  }
  return "connection";
}

ClientError reply_error(protocol::ErrorCode code, std::string message) {
  return ClientError{ClientErrc::reply, std::move(message), code, std::string(protocol::to_string(code))};
}

std::expected<Endpoint, std::string> parse_connect(const std::string& text) {
  const auto bad = [&](const std::string& why) {
    return std::unexpected("--connect: " + why + ", got '" + text + "' (expected HOST:PORT, e.g. 127.0.0.1:7300)");
  };
  const auto colon = text.rfind(':');
  if (colon == std::string::npos) return bad("no port");
  std::string host = text.substr(0, colon);
  const std::string port = text.substr(colon + 1);
  if (host.size() >= 2 && host.front() == '[' && host.back() == ']') host = host.substr(1, host.size() - 2);
  if (host.empty()) return bad("no host");
  if (port.empty() || port.size() > 5 || port.find_first_not_of("0123456789") != std::string::npos)
    return bad("the port is not a number");
  const long p = std::stol(port);
  if (p < 1 || p > 65535) return bad("the port is not in 1..65535");
  Endpoint e;
  e.tcp_host = host;
  e.tcp_port = static_cast<std::uint16_t>(p);
  return e;
}

namespace {

std::unexpected<ClientError> fail(ClientErrc code, std::string message) {
  return std::unexpected(ClientError{code, std::move(message), std::nullopt, {}});
}

int remaining_ms(SteadyClock::time_point deadline) {
  const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - SteadyClock::now()).count();
  return left < 0 ? 0 : static_cast<int>(left);
}

}  // namespace

Client::Client(Client&& o) noexcept
    : fd_(std::exchange(o.fd_, -1)), lines_(std::move(o.lines_)), pushed_(std::move(o.pushed_)),
      token_(std::move(o.token_)), next_id_(o.next_id_), hello_(std::move(o.hello_)) {}

Client& Client::operator=(Client&& o) noexcept {
  if (this != &o) {
    if (fd_ >= 0) ::close(fd_);
    fd_ = std::exchange(o.fd_, -1);
    lines_ = std::move(o.lines_);
    pushed_ = std::move(o.pushed_);
    token_ = std::move(o.token_);
    next_id_ = o.next_id_;
    hello_ = std::move(o.hello_);
  }
  return *this;
}

Client::~Client() {
  if (fd_ >= 0) ::close(fd_);
}

std::expected<Client, ClientError> Client::connect(const std::string& path, int timeout_ms) {
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  if (path.size() >= sizeof addr.sun_path) return fail(ClientErrc::connection, "socket path too long: " + path);
  std::memcpy(addr.sun_path, path.c_str(), path.size() + 1);
  const int fd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return fail(ClientErrc::connection, std::string("socket: ") + std::strerror(errno));
  // A unix stream connect completes or fails at once (or waits for a full backlog briefly).
  if (::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) {
    const int err = errno;
    ::close(fd);
    return fail(ClientErrc::connection, "cannot connect to fogbenchd at " + path + ": " + std::strerror(err) +
                                  " (is it running? --socket or $FOGBENCH_SOCKET)");
  }
  return handshake(fd, timeout_ms);
}

std::expected<Client, ClientError> Client::handshake(int fd, int timeout_ms) {
  Client c(fd);
  auto hello = c.read_message(timeout_ms);
  if (!hello) return std::unexpected(hello.error());
  // A daemon that refuses the connection says why in an error line instead of its hello (too
  // many clients on this listener or from this address: docs/reliability.md): that reason.
  if (hello->is_object() && hello->contains("error") && (*hello)["error"].is_object()) {
    const json& e = (*hello)["error"];
    const std::string code = e.value("code", json()).is_string() ? e["code"].get<std::string>() : "internal";
    const std::string why = e.value("message", json()).is_string() ? e["message"].get<std::string>() : e.dump();
    return std::unexpected(ClientError{ClientErrc::reply, "fogbenchd refused the connection: " + why,
                                       protocol::error_code_from_string(code), code});
  }
  // A daemon of another protocol version is refused here, before any request is sent.
  if (auto h = protocol::hello_from_json(*hello); !h) return fail(ClientErrc::protocol, h.error());
  c.hello_ = *hello;
  return c;
}

std::expected<Client, ClientError> Client::connect(const Endpoint& e, const std::string& token, int timeout_ms) {
  std::expected<Client, ClientError> c = std::unexpected(ClientError{ClientErrc::connection, "no endpoint", std::nullopt, {}});
  if (e.tcp_host.empty()) {
    c = connect(e.socket_path, timeout_ms);
  } else {
    const std::string where = e.tcp_host + ":" + std::to_string(e.tcp_port);
    addrinfo hints{};
    hints.ai_family = AF_UNSPEC;
    hints.ai_socktype = SOCK_STREAM;
    addrinfo* found = nullptr;
    if (int rc = ::getaddrinfo(e.tcp_host.c_str(), std::to_string(e.tcp_port).c_str(), &hints, &found); rc != 0)
      return fail(ClientErrc::connection, "cannot resolve " + e.tcp_host + " (--connect): " + ::gai_strerror(rc));
    std::string last_error = "no address";
    const auto deadline = SteadyClock::now() + std::chrono::milliseconds(timeout_ms);
    int fd = -1;
    for (addrinfo* a = found; a && fd < 0; a = a->ai_next) {
      fd = ::socket(a->ai_family, a->ai_socktype | SOCK_CLOEXEC | SOCK_NONBLOCK, a->ai_protocol);
      if (fd < 0) {
        last_error = std::strerror(errno);
        continue;
      }
      // Non-blocking, so an address that does not answer waits no longer than the deadline.
      int err = ::connect(fd, a->ai_addr, a->ai_addrlen) == 0 ? 0 : errno;
      if (err == EINPROGRESS) {
        pollfd p{fd, POLLOUT, 0};
        const int r = ::poll(&p, 1, remaining_ms(deadline));
        socklen_t len = sizeof err;
        if (r <= 0) err = ETIMEDOUT;
        else ::getsockopt(fd, SOL_SOCKET, SO_ERROR, &err, &len);
      }
      if (err != 0) {
        last_error = std::strerror(err);
        ::close(fd);
        fd = -1;
      }
    }
    ::freeaddrinfo(found);
    if (fd < 0)
      return fail(ClientErrc::connection, "cannot connect to fogbenchd at " + where + ": " + last_error +
                                    " (is TCP configured, socket.tcp? --connect)");
    // Blocking again: reads and writes wait with poll() deadlines of their own.
    ::fcntl(fd, F_SETFL, ::fcntl(fd, F_GETFL) & ~O_NONBLOCK);
    c = handshake(fd, timeout_ms);
  }
  if (c) c->token_ = token;
  return c;
}

std::expected<json, ClientError> Client::read_message(int timeout_ms) {
  const auto deadline = SteadyClock::now() + std::chrono::milliseconds(timeout_ms);
  std::string line;
  for (;;) {
    switch (lines_.next(line)) {
      case protocol::LineSplitter::Status::line: {
        if (line.empty()) continue;
        // The daemon's own limits on nesting and duplicate keys: a deep line is refused, never built.
        auto j = protocol::parse_line(line);
        if (!j || !j->is_object())
          return fail(ClientErrc::protocol, "the daemon sent a line that is not a JSON object" +
                                      (j ? std::string() : " (" + j.error() + ")"));
        return std::move(*j);
      }
      case protocol::LineSplitter::Status::too_long:
        return fail(ClientErrc::protocol, "the daemon sent a line over " + std::to_string(protocol::kMaxMessageBytes) +
                                    " bytes (the protocol's limit on a message, kMaxMessageBytes); giving up on it");
      case protocol::LineSplitter::Status::incomplete: break;
    }
    pollfd p{fd_, POLLIN, 0};
    const int r = ::poll(&p, 1, remaining_ms(deadline));
    if (r < 0 && errno == EINTR) continue;
    if (r < 0) return fail(ClientErrc::connection, std::string("poll: ") + std::strerror(errno));
    if (r == 0) return fail(ClientErrc::timeout, "no message from the daemon in " + std::to_string(timeout_ms) + " ms");
    char buf[65536];
    const ssize_t n = ::recv(fd_, buf, sizeof buf, 0);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return fail(ClientErrc::connection, "the daemon closed the connection");
    lines_.feed(std::string_view(buf, static_cast<std::size_t>(n)));
  }
}

std::expected<json, ClientError> Client::call(const std::string& cmd, json args, int timeout_ms) {
  const auto id = next_id_++;
  args["id"] = id;
  args["cmd"] = cmd;
  if (!token_.empty()) args["token"] = token_;
  const std::string line = args.dump() + "\n";
  std::size_t sent = 0;
  const auto deadline = SteadyClock::now() + std::chrono::milliseconds(timeout_ms);
  while (sent < line.size()) {
    const ssize_t n = ::send(fd_, line.data() + sent, line.size() - sent, MSG_NOSIGNAL);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
      pollfd p{fd_, POLLOUT, 0};
      if (::poll(&p, 1, remaining_ms(deadline)) <= 0) return fail(ClientErrc::timeout, "the daemon does not read");
      continue;
    }
    if (n < 0) return fail(ClientErrc::connection, std::string("send: ") + std::strerror(errno));
    sent += static_cast<std::size_t>(n);
  }
  for (;;) {
    auto m = read_message(remaining_ms(deadline));
    if (!m) return std::unexpected(m.error());
    if (m->value("type", "") != "reply") {
      pushed_.push_back(std::move(*m));
      continue;
    }
    if ((*m)["id"] != id) continue;  // a reply to an earlier request that timed out
    if (m->contains("error")) {
      const json& e = (*m)["error"];
      const std::string code = e.value("code", "internal");
      ClientError ce = reply_error(protocol::error_code_from_string(code).value_or(protocol::ErrorCode::internal),
                                   e.value("message", "error"));
      ce.reply_code = protocol::error_code_from_string(code);
      ce.reply_code_text = code;
      return std::unexpected(std::move(ce));
    }
    return (*m)["result"];
  }
}

std::expected<json, ClientError> Client::next_message(int timeout_ms) {
  if (!pushed_.empty()) {
    json m = std::move(pushed_.front());
    pushed_.pop_front();
    return m;
  }
  for (;;) {
    auto m = read_message(timeout_ms);
    if (!m) return m;
    if (m->value("type", "") == "reply") continue;
    return m;
  }
}

std::expected<model::RunData, ClientError> fetch_run(Client& c, std::int64_t run_id, int unit,
                                                     bool include_settle, Gaps gaps) {
  model::RunData d;
  d.name = "run " + std::to_string(run_id) + " unit " + std::to_string(unit);
  std::int64_t offset = 0;
  constexpr std::int64_t page = 10000;
  bool any_compensated = false;  // the daemon's live compensation: a column only if any
  bool any_power_on = false;     // since_power_on_s (the term language's ton): a column only if any
  bool any_rate_in = false;      // the commanded table rate: a column only if any
  bool three_axis = false;       // a three-axis unit: its y and z columns
  bool axis_thermistors = false; // with thermistors per axis: y's and z's columns
  for (;;) {
    auto r = c.call("run.samples", {{"run_id", run_id}, {"unit", unit}, {"offset", offset}, {"limit", page}});
    if (!r) return std::unexpected(r.error());
    const json& rows = (*r)["samples"];
    for (const auto& row : rows) {
      auto s = protocol::sample_from_json(row);
      if (!s) return fail(ClientErrc::protocol, "run.samples of run " + std::to_string(run_id) + ": " + s.error());
      const auto phase = model::phase_from_string(s->phase).value_or(model::Phase::unknown);
      if (phase == model::Phase::settle && !include_settle) continue;
      auto val = [](std::optional<double> v) { return v.value_or(std::nan("")); };
      d.time_s.push_back(s->t_s);
      d.gyro_dph.push_back(val(s->gyro_dph));
      d.t1_c.push_back(val(s->t1_c));
      d.t2_c.push_back(val(s->t2_c));
      d.setpoint_c.push_back(val(s->setpoint_c));
      d.chamber_c.push_back(val(s->chamber_c));
      d.phase.push_back(phase);
      d.step.push_back(s->step.value_or(-1));
      d.flags.push_back(s->flags);
      d.compensated_dph.push_back(val(s->compensated_dph));
      any_compensated |= s->compensated_dph.has_value();
      d.since_power_on_s.push_back(val(s->since_power_on_s));
      any_power_on |= s->since_power_on_s.has_value();
      d.rate_in_dps.push_back(val(s->rate_in_dps));
      any_rate_in |= s->rate_in_dps.has_value();
      d.gyro_y_dph.push_back(val(s->gyro_y_dph));
      d.gyro_z_dph.push_back(val(s->gyro_z_dph));
      three_axis |= s->three_axis;  // the daemon sends y and z for a three-axis unit only
      d.axis_t1_c[1].push_back(val(s->t1_y_c));
      d.axis_t2_c[1].push_back(val(s->t2_y_c));
      d.axis_t1_c[2].push_back(val(s->t1_z_c));
      d.axis_t2_c[2].push_back(val(s->t2_z_c));
      axis_thermistors |= s->axis_thermistors;  // and y's and z's thermistors where it has them
    }
    offset += static_cast<std::int64_t>(rows.size());
    if (rows.size() < static_cast<std::size_t>(page) || offset >= (*r)["total"].get<std::int64_t>()) break;
  }
  if (d.time_s.empty())
    return std::unexpected(reply_error(protocol::ErrorCode::not_found, "run " + std::to_string(run_id) + " unit " +
                                                                           std::to_string(unit) + " has no samples"));
  if (!any_compensated) d.compensated_dph.clear();
  if (!any_power_on) d.since_power_on_s.clear();
  if (!any_rate_in) d.rate_in_dps.clear();
  if (!three_axis) {
    d.gyro_y_dph.clear();
    d.gyro_z_dph.clear();
  }
  if (three_axis && axis_thermistors) {
    d.axis_t1_c[0] = d.t1_c;
    d.axis_t2_c[0] = d.t2_c;
  } else {
    for (std::size_t k = 1; k < 3; ++k) {
      d.axis_t1_c[k].clear();
      d.axis_t2_c[k].clear();
    }
  }
  if (gaps == Gaps::bridge) {
    // A value not read takes its neighbour's, and the sample keeps (or gets) the missing flag
    // so that no fit trusts it.
    storage::bridge_missing(d);
    return d;
  }
  // Kept as NaN: the sample must carry the missing flag, which is what lets the CSV hold an
  // empty cell there (docs/csv.md); the store sets it, this makes sure of it.
  for (std::size_t i = 0; i < d.size(); ++i)
    for (const auto* col : {&d.gyro_dph, &d.t1_c, &d.t2_c, &d.setpoint_c, &d.chamber_c})
      if (!std::isfinite((*col)[i])) d.flags[i] |= model::flag::missing;
  return d;
}

}  // namespace fogbench::cli
