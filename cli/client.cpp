// fogctl's client commands over fogbenchd's command socket (newline-delimited JSON, see
// docs/protocol.md). Plain blocking POSIX sockets with poll() deadlines: a command-line tool
// waits for one thing at a time.
#include "client.hpp"

#include <fcntl.h>
#include <netdb.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <sstream>
#include <thread>

#include "common.hpp"
#include "fogbench/protocol/framing.hpp"
#include "fogbench/protocol/protocol.hpp"
#include "fogbench/storage/csv.hpp"
#include "table.hpp"

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

std::unexpected<ClientError> fail(std::string code, std::string message) {
  return std::unexpected(ClientError{std::move(code), std::move(message)});
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
  if (path.size() >= sizeof addr.sun_path) return fail("connection", "socket path too long: " + path);
  std::memcpy(addr.sun_path, path.c_str(), path.size() + 1);
  const int fd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return fail("connection", std::string("socket: ") + std::strerror(errno));
  // A unix stream connect completes or fails at once (or waits for a full backlog briefly).
  if (::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) {
    const int err = errno;
    ::close(fd);
    return fail("connection", "cannot connect to fogbenchd at " + path + ": " + std::strerror(err) +
                                  " (is it running? --socket or $FOGBENCH_SOCKET)");
  }
  return handshake(fd, timeout_ms);
}

std::expected<Client, ClientError> Client::handshake(int fd, int timeout_ms) {
  Client c(fd);
  auto hello = c.read_message(timeout_ms);
  if (!hello) return std::unexpected(hello.error());
  // A daemon of another protocol version is refused here, before any request is sent.
  if (auto h = protocol::hello_from_json(*hello); !h) return fail("protocol", h.error());
  c.hello_ = *hello;
  return c;
}

std::expected<Client, ClientError> Client::connect(const Endpoint& e, const std::string& token, int timeout_ms) {
  std::expected<Client, ClientError> c = std::unexpected(ClientError{"connection", "no endpoint"});
  if (e.tcp_host.empty()) {
    c = connect(e.socket_path, timeout_ms);
  } else {
    const std::string where = e.tcp_host + ":" + std::to_string(e.tcp_port);
    addrinfo hints{};
    hints.ai_family = AF_UNSPEC;
    hints.ai_socktype = SOCK_STREAM;
    addrinfo* found = nullptr;
    if (int rc = ::getaddrinfo(e.tcp_host.c_str(), std::to_string(e.tcp_port).c_str(), &hints, &found); rc != 0)
      return fail("connection", "cannot resolve " + e.tcp_host + " (--connect): " + ::gai_strerror(rc));
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
      return fail("connection", "cannot connect to fogbenchd at " + where + ": " + last_error +
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
          return fail("protocol", "the daemon sent a line that is not a JSON object" +
                                      (j ? std::string() : " (" + j.error() + ")"));
        return std::move(*j);
      }
      case protocol::LineSplitter::Status::too_long:
        return fail("protocol", "the daemon sent a line over " + std::to_string(protocol::kMaxMessageBytes) +
                                    " bytes (the protocol's limit on a message, kMaxMessageBytes); giving up on it");
      case protocol::LineSplitter::Status::incomplete: break;
    }
    pollfd p{fd_, POLLIN, 0};
    const int r = ::poll(&p, 1, remaining_ms(deadline));
    if (r < 0 && errno == EINTR) continue;
    if (r < 0) return fail("connection", std::string("poll: ") + std::strerror(errno));
    if (r == 0) return fail("timeout", "no message from the daemon in " + std::to_string(timeout_ms) + " ms");
    char buf[65536];
    const ssize_t n = ::recv(fd_, buf, sizeof buf, 0);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return fail("connection", "the daemon closed the connection");
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
      if (::poll(&p, 1, remaining_ms(deadline)) <= 0) return fail("timeout", "the daemon does not read");
      continue;
    }
    if (n < 0) return fail("connection", std::string("send: ") + std::strerror(errno));
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
      return fail(e.value("code", "internal"), e.value("message", "error"));
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
                                                     bool include_settle) {
  model::RunData d;
  d.name = "run " + std::to_string(run_id) + " unit " + std::to_string(unit);
  std::int64_t offset = 0;
  constexpr std::int64_t page = 10000;
  for (;;) {
    auto r = c.call("run.samples", {{"run_id", run_id}, {"unit", unit}, {"offset", offset}, {"limit", page}});
    if (!r) return std::unexpected(r.error());
    const json& rows = (*r)["samples"];
    for (const auto& row : rows) {
      auto s = protocol::sample_from_json(row);
      if (!s) return fail("protocol", "run.samples of run " + std::to_string(run_id) + ": " + s.error());
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
    }
    offset += static_cast<std::int64_t>(rows.size());
    if (rows.size() < static_cast<std::size_t>(page) || offset >= (*r)["total"].get<std::int64_t>()) break;
  }
  if (d.time_s.empty()) return fail("not_found", "run " + std::to_string(run_id) + " unit " + std::to_string(unit) + " has no samples");
  // The CSV has no empty cells: a value not read takes its neighbour's, and the sample keeps
  // (or gets) the missing flag so that no fit trusts it.
  for (auto* col : {&d.gyro_dph, &d.t1_c, &d.t2_c, &d.setpoint_c, &d.chamber_c}) {
    auto& v = *col;
    std::optional<double> first;
    for (double x : v)
      if (std::isfinite(x)) {
        first = x;
        break;
      }
    double last = first.value_or(0.0);
    for (std::size_t i = 0; i < v.size(); ++i) {
      if (std::isfinite(v[i])) {
        last = v[i];
      } else {
        v[i] = last;
        d.flags[i] |= model::flag::missing;
      }
    }
  }
  return d;
}

namespace {

struct Common {
  std::string socket = default_socket();
  std::string connect;  // HOST:PORT: the daemon's TCP endpoint instead of the unix socket
  std::string token = default_token();
  bool json_out = false;
};

void add_common(CLI::App* c, Common& o, bool with_json = true) {
  c->add_option("--socket", o.socket, "fogbenchd's socket (default: $FOGBENCH_SOCKET or /run/fogbench/fogbenchd.sock)");
  c->add_option("--connect", o.connect,
                "HOST:PORT: talk to fogbenchd over TCP (socket.tcp) instead of the unix socket; reads need "
                "nothing, control commands need --token");
  c->add_option("--token", o.token,
                "The daemon's socket.tcp.token, for control commands over TCP (default: $FOGBENCH_TOKEN; the "
                "variable keeps it out of the process list)");
  if (with_json) c->add_flag("--json", o.json_out, "Print JSON for machines");
}

std::string num_text(const json& v, int digits = 2) {
  return v.is_number() ? fixed(v.get<double>(), digits) : "-";
}
std::string num_text(std::optional<double> v, int digits = 2) {
  return v && std::isfinite(*v) ? fixed(*v, digits) : "-";
}
std::string num_text(double v, int digits = 2) { return num_text(std::optional<double>(v), digits); }

std::string duration_text(double s) {
  if (!std::isfinite(s) || s < 0) return "-";
  const auto t = static_cast<long long>(std::llround(s));
  char buf[32];
  std::snprintf(buf, sizeof buf, "%lld:%02lld:%02lld", t / 3600, (t / 60) % 60, t % 60);
  return buf;
}

int report(const ClientError& e, std::ostream& err) {
  const bool plain = e.code == "connection" || e.code == "timeout" || e.code == "bad_option" || e.code == "protocol";
  err << "fogctl: " << (plain ? "" : e.code + ": ") << e.message << "\n";
  return kExitError;
}

std::expected<Client, ClientError> open(const Common& o) {
  Endpoint e;
  e.socket_path = o.socket;
  if (!o.connect.empty()) {
    auto tcp = parse_connect(o.connect);
    if (!tcp) return std::unexpected(ClientError{"bad_option", tcp.error()});
    e = *tcp;
  }
  return Client::connect(e, o.token);
}

// Per unit of a run, what it lost: frames lost and corrupt, samples flagged (`quality` of
// status.run and of run.get). "-" where the daemon has no counts (a run interrupted by a crash).
Table quality_table(const json& serials, const json& quality, const json* samples = nullptr) {
  std::vector<std::string> head = {"unit", "serial"};
  if (samples) head.push_back("samples");
  for (const char* h : {"frames_lost", "frames_corrupt", "samples_flagged"}) head.push_back(h);
  Table t(head);
  for (std::size_t i = 0; i < serials.size(); ++i) {
    std::vector<std::string> row = {std::to_string(i), serials[i].get<std::string>()};
    if (samples) row.push_back(i < samples->size() ? std::to_string((*samples)[i].get<std::int64_t>()) : "-");
    const json* q = nullptr;
    if (quality.is_array())
      for (const auto& x : quality)
        if (x.value("unit", -1) == static_cast<int>(i)) q = &x;
    for (const char* k : {"frames_lost", "frames_corrupt", "samples_flagged"})
      row.push_back(q && (*q)[k].is_number_integer() ? std::to_string((*q)[k].get<std::int64_t>()) : "-");
    t.add(row);
  }
  return t;
}

// --- status
int cmd_status(const Common& o, std::ostream& out, std::ostream& err) {
  auto c = open(o);
  if (!c) return report(c.error(), err);
  auto s = c->call("status");
  if (!s) return report(s.error(), err);
  if (o.json_out) {
    out << s->dump() << "\n";
    return kExitOk;
  }
  const json& ch = (*s)["chamber"];
  out << "fogbenchd " << (*s)["version"].get<std::string>() << (s->value("simulated", false) ? " (simulated" : " (hardware")
      << ", time scale " << (*s)["time_scale"].get<double>() << ")\n";
  out << "chamber: " << num_text(ch["chamber_c"]) << " C, setpoint " << num_text(ch["setpoint_c"]) << " C (commanded "
      << num_text((*s)["setpoint_c"]) << " C), link " << ch["link"].get<std::string>()
      << (ch.value("alarm", false) ? ", ALARM" : "") << "\n";
  Table t({"unit", "gyro_dph", "frames", "t1_c", "t2_c"});
  for (const auto& u : (*s)["units"])
    t.add({u["serial"].get<std::string>(), num_text(u["gyro_dph"], 3), std::to_string(u.value("frames", 0)),
           num_text(u["t1_c"]), num_text(u["t2_c"])});
  out << t.str();
  const json& r = (*s)["run"];
  if (r.is_null()) {
    out << "no run active\n";
  } else {
    out << "run " << r["id"] << ": " << r["state"].get<std::string>() << ", " << r["purpose"].get<std::string>()
        << " on " << r["profile"].get<std::string>() << ", phase "
        << (r["phase"].is_string() ? r["phase"].get<std::string>() : "-") << ", elapsed "
        << duration_text(r["elapsed_s"].get<double>()) << ", remaining "
        << (r["remaining_s"].is_number() ? duration_text(r["remaining_s"].get<double>()) : "-") << "\n";
    out << "data quality of the run:\n" << quality_table(r["units"], r.value("quality", json())).str();
  }
  const json& last = s->value("last_run", json());
  if (last.is_object())
    out << "last run " << last["run_id"] << ": " << last["state"].get<std::string>() << " ("
        << last["reason"].get<std::string>() << ")"
        << (last.value("recorded", true) ? "" : "; NOT yet recorded in the store (retried every 10 s)") << "\n";
  return kExitOk;
}

// --- run list / get / abort
std::string opt_str(const json& v) { return v.is_string() ? v.get<std::string>() : "-"; }

int cmd_run_list(const Common& o, const std::string& state, int limit, std::ostream& out, std::ostream& err) {
  auto c = open(o);
  if (!c) return report(c.error(), err);
  json args = {{"limit", limit}};
  if (!state.empty()) args["state"] = state;
  auto r = c->call("run.list", args);
  if (!r) return report(r.error(), err);
  if (o.json_out) {
    out << r->dump() << "\n";
    return kExitOk;
  }
  Table t({"run", "state", "purpose", "profile", "units", "started", "ended", "reason"});
  for (const auto& run : (*r)["runs"]) {
    std::string units;
    for (const auto& u : run["units"]) units += (units.empty() ? "" : ",") + u.get<std::string>();
    t.add({std::to_string(run["id"].get<std::int64_t>()), run["state"], run["purpose"], run["profile"], units,
           opt_str(run["started_at"]), opt_str(run["ended_at"]), run["reason"]});
  }
  out << t.str();
  return kExitOk;
}

void print_table1(const json& verifications, const json& run, std::ostream& out) {
  Table t({"unit", "serial", "model", "est_mean", "meas_mean", "est_std", "meas_std", "comp_std", "ratio", "pass"});
  for (const auto& v : verifications) {
    // model::to_json(Verification) puts the whole run's Table 1 at the top level.
    const json& res = v["result"];
    const json& r = res.contains("run") && res["run"].is_object() ? res["run"] : res;
    const int unit = v["unit"].get<int>();
    t.add({std::to_string(unit), run["units"][static_cast<std::size_t>(unit)].get<std::string>(),
           std::to_string(v["model_id"].get<std::int64_t>()), num_text(r["est_mean"]), num_text(r["meas_mean"]),
           num_text(r["est_std"]), num_text(r["meas_std"]), num_text(r["comp_std"]), num_text(r["ratio"], 3),
           v["pass"].get<bool>() ? "yes" : res.value("verdict", "") == "marginal" ? "MARGINAL" : "NO"});
  }
  out << t.str();
}

int cmd_run_get(const Common& o, std::int64_t id, std::ostream& out, std::ostream& err) {
  auto c = open(o);
  if (!c) return report(c.error(), err);
  auto r = c->call("run.get", {{"run_id", id}});
  if (!r) return report(r.error(), err);
  if (o.json_out) {
    out << r->dump() << "\n";
    return kExitOk;
  }
  const json& run = (*r)["run"];
  out << "run " << id << ": " << run["state"].get<std::string>() << " (" << run["reason"].get<std::string>() << ")\n"
      << "  purpose " << run["purpose"].get<std::string>() << ", profile " << run["profile"].get<std::string>()
      << ", time scale " << run["time_scale"] << "\n  created " << run["created_at"].get<std::string>() << ", started "
      << opt_str(run["started_at"]) << ", ended " << opt_str(run["ended_at"]) << "\n";
  if (!run.value("recorded", true))
    out << "  its end is NOT yet recorded in the store (a full disk?); the daemon retries every 10 s\n";
  // Per unit: the samples stored and what the run lost (frames lost, corrupt, samples flagged).
  out << quality_table(run["units"], r->value("quality", json()), &(*r)["samples"]).str();
  if (!(*r)["models"].empty()) {
    Table t({"model", "serial", "version", "method", "terms", "parent"});
    for (const auto& m : (*r)["models"])
      t.add({std::to_string(m["id"].get<std::int64_t>()), m["serial"], std::to_string(m["version"].get<int>()),
             m["method"], m["terms"], m["parent_id"].is_null() ? "-" : std::to_string(m["parent_id"].get<std::int64_t>())});
    out << "models fitted on this run:\n" << t.str();
  }
  if (!(*r)["verifications"].empty()) {
    out << "verifications (Table 1, deg/h):\n";
    print_table1((*r)["verifications"], run, out);
  }
  Table ev({"t_s", "kind", "detail"});
  for (const auto& e : (*r)["events"])
    ev.add({e["t_s"].is_number() ? fixed(e["t_s"].get<double>(), 0) : "-", e["kind"], e["detail"].dump()});
  out << "events:\n" << ev.str();
  return kExitOk;
}

int cmd_run_abort(const Common& o, const std::string& reason, std::ostream& out, std::ostream& err) {
  auto c = open(o);
  if (!c) return report(c.error(), err);
  json args = json::object();
  if (!reason.empty()) args["reason"] = reason;
  auto r = c->call("run.abort", args);
  if (!r) return report(r.error(), err);
  if (o.json_out) out << r->dump() << "\n";
  else out << "run " << (*r)["run_id"] << " aborted; the chamber returns to its safe setpoint\n";
  return kExitOk;
}

int cmd_run_export(const Common& o, std::int64_t id, int unit, bool settle, const std::string& output,
                   std::ostream& out, std::ostream& err) {
  auto c = open(o);
  if (!c) return report(c.error(), err);
  auto d = fetch_run(*c, id, unit, settle);
  if (!d) return report(d.error(), err);
  const std::string csv = storage::to_csv(*d);
  if (output.empty() || output == "-") {
    out << csv;
    return kExitOk;
  }
  if (auto ok = write_text(output, csv); !ok) {
    err << "fogctl: " << ok.error() << "\n";
    return kExitError;
  }
  if (!o.json_out) err << "run " << id << " unit " << unit << ": " << d->size() << " samples written to " << output << "\n";
  return kExitOk;
}

int cmd_model_get(const Common& o, const std::string& serial, std::int64_t model_id, const std::string& output,
                  std::ostream& out, std::ostream& err) {
  auto c = open(o);
  if (!c) return report(c.error(), err);
  json args = model_id > 0 ? json{{"model_id", model_id}} : json{{"serial", serial}};
  auto m = c->call("model.get", args);
  if (!m) return report(m.error(), err);
  if (!output.empty()) {
    // The model file fogctl verify --model reads.
    if (auto ok = write_text(output, (*m)["model"].dump(2) + "\n"); !ok) {
      err << "fogctl: " << ok.error() << "\n";
      return kExitError;
    }
  }
  if (o.json_out) {
    out << m->dump() << "\n";
  } else {
    out << "model " << (*m)["id"] << " for " << (*m)["serial"].get<std::string>() << ", version " << (*m)["version"]
        << ", fitted on run " << ((*m)["run_id"].is_null() ? std::string("-") : (*m)["run_id"].dump()) << " ("
        << (*m)["method"].get<std::string>() << "): " << (*m)["terms"].get<std::string>() << "\n";
    const json& mj = (*m)["model"];
    if (mj.contains("mu0_dph")) out << "  mu0 " << num_text(mj["mu0_dph"], 3) << " deg/h";
    if (mj.contains("sigma_a_dph")) out << ", sigma_a " << num_text(mj["sigma_a_dph"], 3) << " deg/h";
    out << "\n";
    if (!output.empty()) out << "  written to " << output << "\n";
  }
  return kExitOk;
}

// --- watching a run: the progress line and the end of the run
struct WatchResult {
  std::string state;  // the terminal state, or "" when the connection failed for good
  int code = kExitError;
};

// The exit code of a finished run: 0 completed (and every verification passed), 3 marginal, 1 a
// verification failed, 2 anything else.
int final_code(Client& c, std::int64_t run_id, std::ostream& out, bool json_out) {
  auto r = c.call("run.get", {{"run_id", run_id}});
  if (!r) return report(r.error(), std::cerr);
  const json& run = (*r)["run"];
  if (json_out) out << r->dump() << "\n";
  else out << "run " << run_id << " " << run["state"].get<std::string>() << ": " << run["reason"].get<std::string>() << "\n";
  if (run["state"] != "completed") return kExitError;
  bool all_pass = true, any_fail = false;
  for (const auto& v : (*r)["verifications"]) {
    all_pass = all_pass && v.value("pass", false);
    // marginal (issue 10): the paper's ratio passed, the second test did not (exit 3)
    const bool marginal = v.contains("result") && v["result"].is_object() && v["result"].value("verdict", "") == "marginal";
    any_fail = any_fail || (!v.value("pass", false) && !marginal);
  }
  if (!json_out) {
    for (const auto& m : (*r)["models"])
      out << "model " << m["id"] << " for " << m["serial"].get<std::string>() << " (version " << m["version"]
          << "): " << m["terms"].get<std::string>() << "\n";
    if (!(*r)["verifications"].empty()) print_table1((*r)["verifications"], run, out);
    for (const auto& e : (*r)["events"])
      if (e["kind"] == "note" && e["detail"].value("ok", true) == false)
        out << "analysis of unit " << e["detail"]["unit"] << " failed: " << e["detail"].value("error", "") << "\n";
  }
  return all_pass ? kExitOk : any_fail ? kExitFailed : kExitMarginal;
}

bool terminal(const std::string& s) {
  return s == "completed" || s == "aborted" || s == "failed" || s == "interrupted";
}

// Follows a run until it ends, reconnecting (every second, up to reconnect_s) when the daemon
// goes away. Progress on `err`, unless quiet.
int watch(const Common& o, std::optional<std::int64_t> run_id, bool quiet, double reconnect_s, std::ostream& out,
          std::ostream& err) {
  const bool tty_line = !quiet;
  auto lost_since = SteadyClock::now();
  bool warned = false;
  for (;;) {
    auto c = open(o);
    if (!c && c.error().code == "bad_option") return report(c.error(), err);
    if (!c) {
      if (std::chrono::duration<double>(SteadyClock::now() - lost_since).count() > reconnect_s)
        return report(c.error(), err);
      if (!warned) err << "\nfogctl: " << c.error().message << "; retrying\n";
      warned = true;
      std::this_thread::sleep_for(std::chrono::seconds(1));
      continue;
    }
    warned = false;
    // Subscribe first, then look at the state: nothing can end unseen in between.
    if (auto s = c->call("subscribe"); !s) return report(s.error(), err);
    auto st = c->call("status");
    if (!st) return report(st.error(), err);
    const json& active = (*st)["run"];
    if (!run_id) {
      if (active.is_null()) {
        err << "fogctl: no run is active\n";
        return kExitError;
      }
      run_id = active["id"].get<std::int64_t>();
    }
    if (active.is_null() || active["id"] != *run_id) {
      auto g = c->call("run.get", {{"run_id", *run_id}});
      if (!g) return report(g.error(), err);
      if (terminal((*g)["run"]["state"])) return final_code(*c, *run_id, out, o.json_out);
    }
    std::map<int, protocol::SampleMessage> latest;  // by unit
    auto last_draw = SteadyClock::now() - std::chrono::seconds(1);
    for (;;) {
      auto m = c->next_message(30000);
      if (!m) {
        if (m.error().code == "timeout") continue;  // a long settle: quiet but alive
        if (tty_line) err << "\nfogctl: connection to fogbenchd lost; reconnecting\n";
        lost_since = SteadyClock::now();
        break;
      }
      if ((*m)["run_id"] != *run_id) continue;
      if ((*m)["type"] == "sample") {
        auto s = protocol::sample_message_from_json(*m);
        if (!s) return report(ClientError{"protocol", s.error()}, err);
        latest[s->unit] = *s;
        const auto now = SteadyClock::now();
        if (tty_line && now - last_draw > std::chrono::milliseconds(200)) {
          last_draw = now;
          std::ostringstream line;
          line << "\rrun " << *run_id << " " << s->state << " " << s->phase << " step " << s->step << "  "
               << duration_text(s->elapsed_s) << " elapsed, " << duration_text(s->remaining_s) << " left  chamber "
               << num_text(s->chamber_c, 1) << "/" << num_text(s->setpoint_c, 1) << " C";
          for (const auto& [u, x] : latest)
            line << "  " << x.serial << " T1 " << num_text(x.t1_c) << " T2 " << num_text(x.t2_c) << " drift "
                 << num_text(x.gyro_dph) << " dph";
          line << "   ";
          err << line.str() << std::flush;
        }
      } else if ((*m)["type"] == "event") {
        auto e = protocol::event_message_from_json(*m);
        if (!e) return report(ClientError{"protocol", e.error()}, err);
        if (e->kind != "state") continue;
        const std::string to = e->detail.value("to", "");
        if (tty_line) err << "\n" << "run " << *run_id << ": " << to << " (" << e->detail.value("reason", "") << ")\n";
        if (terminal(to)) {
          // The analysis events follow the state change; run.get is answered after them. A
          // daemon that is stopping closes this connection right after the event: the
          // summary then comes from a new connection (the outer loop), when it is back.
          auto g = c->call("run.get", {{"run_id", *run_id}});
          if (g) return final_code(*c, *run_id, out, o.json_out);
          lost_since = SteadyClock::now();
          break;
        }
      }
    }
  }
}

int cmd_run_start(const Common& o, const std::string& profile, const std::vector<std::string>& units,
                  const std::string& purpose, bool wait, bool quiet, std::ostream& out, std::ostream& err) {
  auto c = open(o);
  if (!c) return report(c.error(), err);
  auto r = c->call("run.start", {{"profile", profile}, {"units", units}, {"purpose", purpose}});
  if (!r) return report(r.error(), err);
  const auto id = (*r)["run_id"].get<std::int64_t>();
  if (!wait) {
    if (o.json_out) out << r->dump() << "\n";
    else out << "run " << id << " started\n";
    return kExitOk;
  }
  if (!o.json_out) err << "run " << id << " started\n";
  return watch(o, id, quiet, 300.0, out, err);
}

// run.resume: an interrupted run (a crash left it) goes on from where its profile clock stood.
int cmd_run_resume(const Common& o, std::int64_t id, bool wait, bool quiet, std::ostream& out, std::ostream& err) {
  auto c = open(o);
  if (!c) return report(c.error(), err);
  auto r = c->call("run.resume", {{"run_id", id}});
  if (!r) return report(r.error(), err);
  if (!wait) {
    if (o.json_out) out << r->dump() << "\n";
    else out << "run " << id << " resumes at the next tick; the time it was away is stored flagged\n";
    return kExitOk;
  }
  if (!o.json_out) err << "run " << id << " resumed\n";
  return watch(o, id, quiet, 300.0, out, err);
}

// --- fit / verify on a stored run: the run is fetched into a CSV and the offline command runs
// on it, exactly as on a file.
struct TempFiles {
  std::vector<std::filesystem::path> paths;
  ~TempFiles() {
    std::error_code ec;
    for (const auto& p : paths) std::filesystem::remove(p, ec);
  }
};
TempFiles& temp_files() {
  static TempFiles t;
  return t;
}

std::filesystem::path temp_path(const std::string& stem, const std::string& ext) {
  auto p = std::filesystem::temp_directory_path() /
           ("fogctl-" + stem + "-" + std::to_string(::getpid()) + ext);
  temp_files().paths.push_back(p);
  return p;
}

std::string fetch_to_csv(const Common& where, std::int64_t run_id, int unit) {
  auto c = open(where);
  if (!c) {
    report(c.error(), std::cerr);
    throw CLI::RuntimeError(kExitError);
  }
  auto d = fetch_run(*c, run_id, unit);
  if (!d) {
    report(d.error(), std::cerr);
    throw CLI::RuntimeError(kExitError);
  }
  auto path = temp_path("run" + std::to_string(run_id) + "-unit" + std::to_string(unit), ".csv");
  if (auto ok = storage::write_csv_file(path, *d); !ok) {
    std::cerr << "fogctl: " << ok.error().message << "\n";
    throw CLI::RuntimeError(kExitError);
  }
  return path.string();
}

}  // namespace

// The subcommand of that name, or null (CLI11 2.1's get_subcommand throws).
CLI::App* find_subcommand(CLI::App& app, const std::string& name) {
  auto subs = app.get_subcommands([&](CLI::App* a) { return a->get_name() == name; });
  return subs.empty() ? nullptr : subs.front();
}

void add_client_commands(CLI::App& app, int& code) {
  static Common common;
  auto* status = app.add_subcommand("status", "Show the daemon, the chamber, the units, the active run with its data quality, and the last run");
  add_common(status, common);
  status->callback([&] { code = cmd_status(common, std::cout, std::cerr); });

  auto* run = app.add_subcommand("run", "Start, follow, list, inspect, abort, resume and export runs on fogbenchd");
  run->require_subcommand(1);

  static std::string profile, purpose = "fit", reason, state, output;
  static std::vector<std::string> units;
  static bool wait = false, quiet = false, settle = false;
  static std::int64_t run_id = 0;
  static int unit = 0, limit = 50;
  static std::optional<std::int64_t> watch_id;

  auto* start = run->add_subcommand("start", "Start a run of a profile on units; --wait follows it to the end");
  add_common(start, common);
  start->add_option("--profile", profile, "Profile name in the daemon's profile directory, e.g. exp1")->required();
  start->add_option("--unit", units, "Serial of a unit under test (repeatable)")->required();
  start->add_option("--purpose", purpose, "fit (a model is fitted at the end) or verify (the current model is checked)")
      ->check(CLI::IsMember({"fit", "verify"}));
  start->add_flag("--wait", wait, "Follow the run with a progress line on stderr until it ends");
  start->add_flag("-q,--quiet", quiet, "With --wait: no progress line");
  start->callback([&] { code = cmd_run_start(common, profile, units, purpose, wait, quiet, std::cout, std::cerr); });

  auto* w = run->add_subcommand("watch", "Follow a run (the active one by default) to its end; reconnects if the daemon restarts");
  add_common(w, common);
  w->add_option("run", watch_id, "Run id (default: the active run)");
  w->add_flag("-q,--quiet", quiet, "No progress line");
  w->callback([&] { code = watch(common, watch_id, quiet, 300.0, std::cout, std::cerr); });

  auto* list = run->add_subcommand("list", "List runs, newest first");
  add_common(list, common);
  list->add_option("--state", state, "Only runs in this state");
  list->add_option("--limit", limit, "At most this many runs");
  list->callback([&] { code = cmd_run_list(common, state, limit, std::cout, std::cerr); });

  auto* get = run->add_subcommand("get", "Show a run: per unit its samples, frames lost and corrupt, samples flagged; models, verifications, audit trail");
  add_common(get, common);
  get->add_option("run", run_id, "Run id")->required();
  get->callback([&] { code = cmd_run_get(common, run_id, std::cout, std::cerr); });

  auto* abort = run->add_subcommand("abort", "Abort the active run; the chamber returns to its safe setpoint");
  add_common(abort, common);
  abort->add_option("--reason", reason, "Why, for the audit trail");
  abort->callback([&] { code = cmd_run_abort(common, reason, std::cout, std::cerr); });

  static bool resume_wait = false;
  auto* resume = run->add_subcommand(
      "resume", "Take up an interrupted run (one a crash of fogbenchd left) where its profile clock stood");
  add_common(resume, common);
  resume->add_option("run", run_id, "Id of the interrupted run")->required();
  resume->add_flag("--wait", resume_wait, "Follow the run with a progress line on stderr until it ends");
  resume->add_flag("-q,--quiet", quiet, "With --wait: no progress line");
  resume->callback([&] { code = cmd_run_resume(common, run_id, resume_wait, quiet, std::cout, std::cerr); });

  auto* exp = run->add_subcommand("export", "Write a stored run's unit as CSV (the format fogctl fit reads)");
  add_common(exp, common);
  exp->add_option("run", run_id, "Run id")->required();
  exp->add_option("--unit", unit, "Unit index in the run (default 0)");
  exp->add_option("-o,--output", output, "CSV file (default: standard output)");
  exp->add_flag("--include-settle", settle, "Keep the samples of the opening settle");
  exp->callback([&] { code = cmd_run_export(common, run_id, unit, settle, output, std::cout, std::cerr); });

  static std::string model_serial, model_output;
  static std::int64_t model_id = 0;
  auto* models = app.add_subcommand("model", "Models stored by fogbenchd");
  models->require_subcommand(1);
  auto* mget = models->add_subcommand("get", "Show a unit's current model (or one by --id); -o writes its JSON file");
  add_common(mget, common);
  mget->add_option("serial", model_serial, "The unit's serial");
  mget->add_option("--id", model_id, "A model by its id instead");
  mget->add_option("-o,--output", model_output, "Write the model's JSON here (the file fogctl verify --model reads)");
  mget->callback([&] {
    if (model_serial.empty() && model_id <= 0) {
      std::cerr << "fogctl model get: give a serial or --id\n";
      code = kExitError;
      return;
    }
    code = cmd_model_get(common, model_serial, model_id, model_output, std::cout, std::cerr);
  });

  // fogctl fit --run N / fogctl verify --run N: the offline commands on a stored run. The run
  // is fetched when --run is parsed (after --socket and --unit, declared before it) and handed
  // to the command as the file it would otherwise be given.
  static Common fit_from, verify_from;
  static int fit_unit = 0, verify_unit = 0;
  if (auto* fit = find_subcommand(app, "fit")) {
    if (auto* pos = fit->get_option_no_throw("run")) {
      pos->required(false);
      add_common(fit, fit_from, /*with_json=*/false);  // --socket, --connect, --token: where --run is fetched
      fit->add_option("--unit", fit_unit, "With --run: unit index in the run (default 0)");
      fit->add_option("--run", "Fit on a run stored by fogbenchd (fetched through its socket) instead of a CSV")
          ->each([pos](const std::string& v) {
            pos->clear();
            pos->add_result(fetch_to_csv(fit_from, std::stoll(v), fit_unit));
            pos->run_callback();
          });
    }
  }
  if (auto* ver = find_subcommand(app, "verify")) {
    auto* pos = ver->get_option_no_throw("runs");
    auto* model = ver->get_option_no_throw("--model");
    if (pos && model) {
      pos->required(false);
      model->required(false);
      add_common(ver, verify_from, /*with_json=*/false);
      ver->add_option("--unit", verify_unit, "With --run: unit index in the run (default 0)");
      ver->add_option("--run", "Verify on a run stored by fogbenchd; without --model, the unit's current model")
          ->each([pos, model](const std::string& v) {
            const auto id = std::stoll(v);
            pos->clear();
            pos->add_result(fetch_to_csv(verify_from, id, verify_unit));
            pos->run_callback();
            if (model->count() == 0) {
              auto c = open(verify_from);
              if (!c) {
                report(c.error(), std::cerr);
                throw CLI::RuntimeError(kExitError);
              }
              auto r = c->call("run.get", {{"run_id", id}});
              if (!r) {
                report(r.error(), std::cerr);
                throw CLI::RuntimeError(kExitError);
              }
              const auto& serials = (*r)["run"]["units"];
              if (verify_unit < 0 || static_cast<std::size_t>(verify_unit) >= serials.size()) {
                std::cerr << "fogctl: run " << id << " has no unit " << verify_unit << "\n";
                throw CLI::RuntimeError(kExitError);
              }
              auto m = c->call("model.get", {{"serial", serials[static_cast<std::size_t>(verify_unit)]}});
              if (!m) {
                report(m.error(), std::cerr);
                throw CLI::RuntimeError(kExitError);
              }
              auto path = temp_path("model" + std::to_string((*m)["id"].get<std::int64_t>()), ".json");
              if (auto ok = write_text(path.string(), (*m)["model"].dump(2)); !ok) {
                std::cerr << "fogctl: " << ok.error() << "\n";
                throw CLI::RuntimeError(kExitError);
              }
              model->add_result(path.string());
              model->run_callback();
            }
          });
    }
  }
}

}  // namespace fogbench::cli
