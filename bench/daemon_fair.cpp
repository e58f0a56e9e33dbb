// fogbenchd under issue 11's starvation attack: while a run acquires on the mock bench at time
// scale 100, N clients each subscribe and pipeline `run.samples` requests (limit 10,000, of a
// stored run of 20,000 samples) and never read; one that the daemon drops reconnects and starts
// again. Another client times `status` round trips for the whole run. At the end the run's
// stored seconds are counted: flagged and missing ones, and the daemon log's "late" lines.
// Run it with 0 clients for the same figures without the attack.
// Usage: bench_daemon_fair [clients=64] [time_scale=100] [profile=exp1] [synchronous=normal] [units=2]
#include <fcntl.h>
#include <sys/socket.h>
#include <sys/un.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <thread>

#include "daemon_bench.hpp"
#include "fogbench/storage/samples.hpp"
#include "fogbench/storage/store.hpp"

using namespace fogbench::bench;
namespace storage = fogbench::storage;

namespace {

// A stored run for the attackers to page through: 20,000 seconds of one unit.
void store_long_run(const std::filesystem::path& dir) {
  auto store = storage::Store::open(dir / "fogbench.db");
  if (!store) LiveBench::fail("store: " + store.error().message);
  fogbench::model::RunData d;
  for (int i = 0; i < 20000; ++i) {
    d.time_s.push_back(i);
    d.gyro_dph.push_back(-8.0 + 0.01 * std::sin(i * 0.01));
    d.t1_c.push_back(20.0 + 5.0 * std::sin(i * 1e-3));
    d.t2_c.push_back(20.5 + 5.0 * std::sin(i * 1e-3));
    d.setpoint_c.push_back(20.0);
    d.chamber_c.push_back(20.0);
  }
  storage::ImportOptions o;
  o.serial = "SIM-0001";
  if (auto id = store->import_run(d, o); !id) LiveBench::fail("import: " + id.error().message);
}

// A client that asks and never reads: a non-blocking unix socket and the bytes not yet sent.
struct Attacker {
  int fd = -1;
  std::string unsent;
  std::int64_t next_id = 1;
  int connects = 0;
};

int connect_unix(const std::filesystem::path& path) {
  sockaddr_un a{};
  a.sun_family = AF_UNIX;
  std::strncpy(a.sun_path, path.c_str(), sizeof a.sun_path - 1);
  const int fd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0) {
    ::close(fd);
    return -1;
  }
  return fd;
}

}  // namespace

int main(int argc, char** argv) {
  const int clients = argc > 1 ? std::atoi(argv[1]) : 64;
  const double scale = argc > 2 ? std::atof(argv[2]) : 100.0;
  const std::string profile = argc > 3 ? argv[3] : "exp1";
  const std::string sync = argc > 4 ? argv[4] : "normal";
  const int units = argc > 5 ? std::atoi(argv[5]) : 2;
  LiveBench bench(argv[0], units, scale, sync, store_long_run);

  LineClient c(bench.socket());
  if (!c.ok() || !c.line(10s)) LiveBench::fail("connect failed");
  json serials = json::array();
  for (int u = 1; u <= units; ++u) {
    char s[16];
    std::snprintf(s, sizeof s, "SIM-%04d", u);
    serials.push_back(s);
  }
  auto start = c.call({{"cmd", "run.start"}, {"profile", profile}, {"units", serials}});
  if (!start.contains("result")) LiveBench::fail("run.start: " + start.dump());
  const auto run = start["result"]["run_id"].get<std::int64_t>();

  // The attack: every 10 ms each attacker's socket is topped up with requests as far as the
  // kernel takes them; a dropped one (EPIPE) connects again.
  std::atomic<bool> stop{false};
  std::vector<Attacker> attackers(static_cast<std::size_t>(clients));
  std::thread attack([&] {
    while (!stop) {
      for (auto& a : attackers) {
        if (a.fd < 0) {
          a.fd = connect_unix(bench.socket());
          if (a.fd < 0) continue;
          ++a.connects;
          a.unsent = R"({"id":0,"cmd":"subscribe"})" "\n";
        }
        while (a.unsent.size() < 4096) {
          const auto id = a.next_id++;
          a.unsent += R"({"id":)" + std::to_string(id) + R"(,"cmd":"run.samples","run_id":1,"offset":)" +
                      std::to_string(((id + 1) % 10) * 1000) + R"(,"limit":10000})" "\n";
        }
        const ssize_t n = ::send(a.fd, a.unsent.data(), a.unsent.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
        if (n > 0) a.unsent.erase(0, static_cast<std::size_t>(n));
        else if (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK) {
          ::close(a.fd);
          a.fd = -1;
        }
      }
      std::this_thread::sleep_for(10ms);
    }
    for (auto& a : attackers)
      if (a.fd >= 0) ::close(a.fd);
  });

  // status round trips until the run ends.
  std::vector<double> ms;
  json last;
  for (;;) {
    const auto t0 = std::chrono::steady_clock::now();
    auto r = c.call({{"cmd", "status"}}, 120s);
    const auto t1 = std::chrono::steady_clock::now();
    if (!r.is_object() || !r.contains("result")) LiveBench::fail("status failed");
    ms.push_back(std::chrono::duration<double, std::milli>(t1 - t0).count());
    last = r["result"];
    if (last["run"].is_null()) break;
    std::this_thread::sleep_for(5ms);
  }
  stop = true;
  attack.join();
  int connects = 0;
  for (const auto& a : attackers) connects += a.connects;

  // The run's stored seconds, read from the store itself.
  storage::OpenOptions read_only;
  read_only.read_only = true;
  read_only.create = false;
  auto store = storage::Store::open(bench.dir / "fogbench.db", read_only);
  if (!store) LiveBench::fail("store: " + store.error().message);
  std::int64_t total = 0, flagged = 0, missing = 0, all_null = 0;
  double last_t_s = -1.0;
  for (int u = 0; u < units; ++u) {
    for (std::int64_t off = 0;; off += 10000) {
      auto page = store->get_samples(run, u, off, 10000);
      if (!page) LiveBench::fail("samples: " + page.error().message);
      for (const auto& r : *page) {
        ++total;
        flagged += r.flags != 0;
        missing += (r.flags & fogbench::model::flag::missing) != 0;
        all_null += std::isnan(r.gyro_dph) && std::isnan(r.t1_c) && std::isnan(r.chamber_c);
        last_t_s = std::max(last_t_s, r.t_s);
      }
      if (page->size() < 10000) break;
    }
  }
  int late_lines = 0;
  {
    std::ifstream log(bench.dir / "fogbenchd.log");
    for (std::string l; std::getline(log, l);) late_lines += l.find("late") != std::string::npos;
  }
  std::printf("%d clients pipelining run.samples (limit 10,000) and subscribed, not reading (%d connections made); "
              "run of %s acquiring %d units at time scale %g, synchronous=%s:\n",
              clients, connects, profile.c_str(), units, scale, sync.c_str());
  std::printf("  status: %zu round trips, p50 %.3f ms  p90 %.3f ms  p99 %.3f ms  max %.3f ms\n", ms.size(),
              percentile(ms, 50), percentile(ms, 90), percentile(ms, 99), percentile(ms, 100));
  std::printf("  run %lld %s: %lld samples stored (%d units x %.0f s), %lld flagged, %lld missing, %lld with every value null; "
              "%d 'late' lines in the daemon log\n",
              static_cast<long long>(run), last["last_run"].value("state", "?").c_str(), static_cast<long long>(total),
              units, last_t_s + 1, static_cast<long long>(flagged), static_cast<long long>(missing),
              static_cast<long long>(all_null), late_lines);
  return 0;
}
