// The operator's unix socket under hostile network clients (issue 27, point 1): fogbenchd with
// TCP and the web side on loopback, `hostile` silent token-less connections kept open on each
// (one closed by the daemon, by socket.first_request_timeout_s or a refusal, is opened again at
// once), a run acquiring `units` units at time scale 1; meanwhile one unix client times `status`
// round trips. At the end: the latency percentiles, the connections the hostiles made, and the
// acquisition's skipped seconds (GET /metrics, fogbench_ticks_skipped_total, before and after).
// Usage: bench_daemon_listeners [hostile=256] [requests=3000] [units=2] [max_clients=256]
#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>

#include <atomic>
#include <thread>

#include "daemon_bench.hpp"

using namespace fogbench::bench;

namespace {

int connect_silent(std::uint16_t port) {
  const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_port = htons(port);
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0) {
    ::close(fd);
    return -1;
  }
  return fd;
}

// GET /metrics on a connection of its own; the value of `family` (-1 when not found).
double metric(std::uint16_t port, const std::string& family) {
  const int fd = connect_silent(port);
  if (fd < 0) return -1;
  const std::string req = "GET /metrics HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n";
  if (::send(fd, req.data(), req.size(), MSG_NOSIGNAL) < 0) {
    ::close(fd);
    return -1;
  }
  std::string body;
  char b[65536];
  for (ssize_t n; (n = ::recv(fd, b, sizeof b, 0)) > 0;) body.append(b, static_cast<std::size_t>(n));
  ::close(fd);
  const auto at = body.find("\n" + family + " ");
  if (at == std::string::npos) return -1;
  return std::atof(body.c_str() + at + family.size() + 2);
}

}  // namespace

int main(int argc, char** argv) {
  const int hostile = argc > 1 ? std::atoi(argv[1]) : 256;
  const int requests = argc > 2 ? std::atoi(argv[2]) : 3000;
  const int units = argc > 3 ? std::atoi(argv[3]) : 2;
  const int max_clients = argc > 4 ? std::atoi(argv[4]) : 256;
  const json patch = {{"web", {{"listen", "127.0.0.1:0"}}},
                      {"socket",
                       {{"tcp", {{"port", 0}, {"token", "bench-listeners-token-0123"}}},
                        {"max_clients", max_clients},
                        {"max_clients_per_address", 100000}}}};  // all hostiles are 127.0.0.1
  // socket.tcp.port 0 is refused by the configuration: pick a free port first.
  json p = patch;
  {
    const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    ::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a);
    socklen_t len = sizeof a;
    ::getsockname(fd, reinterpret_cast<sockaddr*>(&a), &len);
    ::close(fd);
    p["socket"]["tcp"]["port"] = ntohs(a.sin_port);
  }
  LiveBench bench(argv[0], units, 1.0, "normal", {}, p);
  const auto tcp_port = p["socket"]["tcp"]["port"].get<std::uint16_t>();
  const std::uint16_t web_port = bench.ready_daemon.value("web_port", json()).is_number()
                                     ? bench.ready_daemon["web_port"].get<std::uint16_t>()
                                     : std::uint16_t{0};
  if (!web_port) LiveBench::fail("no web_port in the ready line");

  LineClient op(bench.socket());
  if (!op.ok() || !op.line(10s)) LiveBench::fail("unix: no hello");
  json units_json = json::array();
  for (int u = 1; u <= units; ++u) {
    char serial[16];
    std::snprintf(serial, sizeof serial, "SIM-%04d", u);
    units_json.push_back(serial);
  }
  auto start = op.call({{"cmd", "run.start"}, {"profile", "exp1"}, {"units", units_json}});
  if (!start.is_object() || !start.contains("result")) LiveBench::fail("run.start: " + start.dump());
  std::this_thread::sleep_for(2s);
  const double skipped0 = metric(web_port, "fogbench_ticks_skipped_total");

  // The hostiles: `hostile` silent connections on each listener, reopened when closed.
  std::atomic<bool> stop{false};
  std::atomic<long> made{0};
  std::thread attack([&] {
    std::vector<pollfd> fds;
    std::vector<std::uint16_t> ports;
    for (int i = 0; i < 2 * hostile; ++i) {
      ports.push_back(i < hostile ? tcp_port : web_port);
      fds.push_back({connect_silent(ports.back()), POLLIN, 0});
      ++made;
    }
    char b[4096];
    while (!stop) {
      ::poll(fds.data(), fds.size(), 50);
      for (std::size_t i = 0; i < fds.size(); ++i) {
        if (fds[i].fd >= 0 && !(fds[i].revents & (POLLIN | POLLHUP | POLLERR))) continue;
        if (fds[i].fd >= 0) {
          const ssize_t n = ::recv(fds[i].fd, b, sizeof b, MSG_DONTWAIT);
          if (n > 0) continue;  // a hello or a refusal's line: read, the connection kept
          ::close(fds[i].fd);
        }
        fds[i].fd = connect_silent(ports[i]);
        ++made;
      }
    }
    for (auto& f : fds)
      if (f.fd >= 0) ::close(f.fd);
  });
  std::this_thread::sleep_for(2s);  // the listeners full

  std::vector<double> ms;
  int failed = 0;
  for (int i = 0; i < requests; ++i) {
    const auto t0 = std::chrono::steady_clock::now();
    auto r = op.call({{"cmd", "status"}}, 10s);
    const auto t1 = std::chrono::steady_clock::now();
    if (!r.is_object() || !r.contains("result")) ++failed;
    else ms.push_back(std::chrono::duration<double, std::milli>(t1 - t0).count());
    std::this_thread::sleep_for(3ms);
  }
  stop = true;
  attack.join();
  std::this_thread::sleep_for(1s);
  double skipped1 = -1;
  for (int i = 0; i < 50 && skipped1 < 0; ++i, std::this_thread::sleep_for(200ms))
    skipped1 = metric(web_port, "fogbench_ticks_skipped_total");
  std::printf("unix status latency, %d silent hostile connections held on TCP and on the web (max_clients %d), "
              "a run acquiring %d units at time scale 1, %d requests (%d failed):\n",
              hostile, max_clients, units, requests, failed);
  std::printf("  p50 %.3f ms  p90 %.3f ms  p99 %.3f ms  max %.3f ms\n", percentile(ms, 50), percentile(ms, 90),
              percentile(ms, 99), percentile(ms, 100));
  std::printf("  hostile connections made: %ld; acquisition seconds skipped during the attack: %.0f\n", made.load(),
              skipped0 >= 0 && skipped1 >= 0 ? skipped1 - skipped0 : -1.0);
  return failed == 0 ? 0 : 1;
}
