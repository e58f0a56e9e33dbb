// Benchmark: decoding and averaging gyro CAN frames for 8 units at 8,000 frames/s each (64,000
// frames/s on one bus), through the AF_UNIX SOCK_SEQPACKET transport fed by a writer thread.
// Reports throughput, the reader's CPU time per simulated second of bus traffic, and checks that
// every frame arrives (SEQPACKET blocks the writer instead of dropping, so a loss is a bug).
#include <poll.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <thread>
#include <vector>

#include "fogbench/drivers/can_frame.hpp"
#include "fogbench/drivers/gyro_bus.hpp"

using namespace fogbench::drivers;
using Clock = std::chrono::steady_clock;

namespace {

constexpr int units = 8;
constexpr int rate_hz = 8000;
constexpr int frames_per_s = units * rate_hz;

double thread_cpu_s() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + static_cast<double>(ts.tv_nsec) * 1e-9;
}

std::vector<GyroChannelConfig> unit_configs() {
  std::vector<GyroChannelConfig> out;
  for (int u = 0; u < units; ++u) {
    GyroChannelConfig c;
    c.node_id = static_cast<std::uint16_t>(0x101 + u);
    c.scale_dph_per_count = 1e-4;
    out.push_back(c);
  }
  return out;
}

// Simulated second `s` of bus traffic: frame k of every unit, interleaved as on a real bus. The
// sequence counter runs on across seconds (8000 is not a multiple of 256).
std::vector<can_frame> one_second(int s) {
  std::vector<can_frame> frames;
  frames.reserve(frames_per_s);
  for (int k = 0; k < rate_hz; ++k) {
    const long n = static_cast<long>(s) * rate_hz + k;
    for (int u = 0; u < units; ++u) {
      frames.push_back(can::encode({static_cast<std::uint16_t>(0x101 + u), 1000 + (k % 7) - 3,
                                    static_cast<std::uint8_t>(n), can::status::valid}));
    }
  }
  return frames;
}

// Sends frames in sendmmsg batches; blocking, so a full receive queue slows the writer down.
void send_frames(int fd, const can_frame* frames, std::size_t n) {
  constexpr std::size_t batch = 64;
  mmsghdr msgs[batch];
  iovec iov[batch];
  std::size_t sent = 0;
  while (sent < n) {
    const std::size_t k = std::min(batch, n - sent);
    for (std::size_t i = 0; i < k; ++i) {
      iov[i] = {const_cast<can_frame*>(&frames[sent + i]), sizeof(can_frame)};
      std::memset(&msgs[i], 0, sizeof msgs[i]);
      msgs[i].msg_hdr.msg_iov = &iov[i];
      msgs[i].msg_hdr.msg_iovlen = 1;
    }
    const int r = ::sendmmsg(fd, msgs, static_cast<unsigned>(k), 0);
    if (r < 0) {
      std::perror("sendmmsg");
      std::exit(1);
    }
    sent += static_cast<std::size_t>(r);
  }
}

struct RunResult {
  std::uint64_t frames = 0;
  double wall_s = 0;
  double reader_cpu_s = 0;
  std::uint64_t lost = 0, corrupt = 0, foreign = 0;
  std::vector<std::uint64_t> unit_frames = std::vector<std::uint64_t>(units, 0);
};

// `paced`: the writer sends 1 ms of traffic (64 frames) every millisecond, as a real bus would;
// otherwise as fast as the reader takes them.
RunResult run(int seconds, bool paced, const std::filesystem::path& sock_path) {
  const int listen_fd = ::socket(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC, 0);
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  std::strncpy(addr.sun_path, sock_path.c_str(), sizeof addr.sun_path - 1);
  ::unlink(sock_path.c_str());
  if (::bind(listen_fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0 ||
      ::listen(listen_fd, 1) != 0) {
    std::perror("bind/listen");
    std::exit(1);
  }
  auto bus = GyroBus::open({"unix:" + sock_path.string()}, unit_configs());
  if (!bus) {
    std::fprintf(stderr, "open: %s\n", bus.error().to_string().c_str());
    std::exit(1);
  }
  const int peer = ::accept(listen_fd, nullptr, nullptr);

  RunResult res;
  const auto start = Clock::now();
  std::thread writer([&] {
    for (int s = 0; s < seconds; ++s) {
      const std::vector<can_frame> second = one_second(s);
      if (!paced) {
        send_frames(peer, second.data(), second.size());
        continue;
      }
      for (int ms = 0; ms < 1000; ++ms) {
        std::this_thread::sleep_until(start + std::chrono::milliseconds(s * 1000 + ms + 1));
        send_frames(peer, second.data() + ms * 64, 64);
      }
    }
  });

  const double cpu0 = thread_cpu_s();
  std::vector<can_frame> buf;
  std::uint64_t in_second = 0;
  const std::uint64_t total = static_cast<std::uint64_t>(seconds) * frames_per_s;
  while (res.frames < total) {
    pollfd p{bus->fd(), POLLIN, 0};
    if (::poll(&p, 1, 2000) <= 0) {
      std::fprintf(stderr, "stalled at %llu frames\n", static_cast<unsigned long long>(res.frames));
      break;
    }
    auto n = bus->read_frames(buf);
    if (!n) {
      std::fprintf(stderr, "read: %s\n", n.error().to_string().c_str());
      break;
    }
    res.frames += *n;
    in_second += *n;
    // Close a sample per simulated second, as the daemon does per wall-clock second.
    if (in_second >= frames_per_s) {
      const BusSample s = bus->close_samples();
      for (std::size_t u = 0; u < s.units.size(); ++u) {
        res.lost += s.units[u].frames_lost;
        res.corrupt += s.units[u].frames_corrupt;
        res.unit_frames[u] += s.units[u].frames;
      }
      res.foreign += s.frames_foreign;
      in_second -= frames_per_s;
    }
  }
  res.reader_cpu_s = thread_cpu_s() - cpu0;
  res.wall_s = std::chrono::duration<double>(Clock::now() - start).count();
  writer.join();
  const BusSample rest = bus->close_samples();
  for (std::size_t u = 0; u < rest.units.size(); ++u) {
    res.lost += rest.units[u].frames_lost;
    res.corrupt += rest.units[u].frames_corrupt;
    res.unit_frames[u] += rest.units[u].frames;
  }
  ::close(peer);
  ::close(listen_fd);
  ::unlink(sock_path.c_str());
  return res;
}

// The decode/filter/average path alone, on frames in memory: the cost without the syscalls.
void route_only(int seconds) {
  auto bus_units = unit_configs();
  // A transport is required by GyroBus; a replay of an empty log is the cheapest one.
  const auto empty = std::filesystem::temp_directory_path() / "fogbench-bench-empty.log";
  { std::FILE* f = std::fopen(empty.c_str(), "w"); std::fclose(f); }
  auto bus = GyroBus::open({"replay:" + empty.string() + "?speed=0"}, bus_units);
  std::vector<std::vector<can_frame>> traffic;
  for (int s = 0; s < seconds; ++s) traffic.push_back(one_second(s));
  const double cpu0 = thread_cpu_s();
  const auto t0 = Clock::now();
  std::uint64_t lost = 0;
  for (int s = 0; s < seconds; ++s) {
    for (const auto& f : traffic[static_cast<std::size_t>(s)]) bus->route(f);
    for (const auto& u : bus->close_samples().units) lost += u.frames_lost;
  }
  const double wall = std::chrono::duration<double>(Clock::now() - t0).count();
  const double cpu = thread_cpu_s() - cpu0;
  const double frames = static_cast<double>(seconds) * frames_per_s;
  std::printf("%-34s %10.0f %8.3f %12.0f %10.3f %12.2f%% %6llu\n", "route() only, frames in memory",
              frames, wall, frames / wall, cpu, 100.0 * cpu / seconds,
              static_cast<unsigned long long>(lost));
  std::filesystem::remove(empty);
}

}  // namespace

int main(int argc, char** argv) {
  const int seconds = argc > 1 ? std::atoi(argv[1]) : 10;
  const int paced_seconds = argc > 2 ? std::atoi(argv[2]) : 5;
  char tmpl[] = "/tmp/fogbench-bench-XXXXXX";
  if (::mkdtemp(tmpl) == nullptr) return 1;
  const std::filesystem::path dir = tmpl;

  std::printf("gyro CAN decode: %d units x %d frames/s = %d frames per simulated second\n\n",
              units, rate_hz, frames_per_s);
  std::printf("%-34s %10s %8s %12s %10s %13s %6s\n", "path", "frames", "wall s", "frames/s",
              "reader CPU", "CPU/sim. s", "lost");
  route_only(seconds);
  for (bool paced : {false, true}) {
    const int s = paced ? paced_seconds : seconds;
    const RunResult r = run(s, paced, dir / "can.sock");
    std::printf("%-34s %10llu %8.3f %12.0f %10.3f %12.2f%% %6llu\n",
                paced ? "unix SEQPACKET, paced 1 ms bursts" : "unix SEQPACKET, writer flat out",
                static_cast<unsigned long long>(r.frames), r.wall_s,
                static_cast<double>(r.frames) / r.wall_s, r.reader_cpu_s,
                100.0 * r.reader_cpu_s / s, static_cast<unsigned long long>(r.lost));
    const std::uint64_t expected = static_cast<std::uint64_t>(s) * frames_per_s;
    bool every_unit = true;  // each unit's frames, summed over its samples, are all it sent
    for (auto f : r.unit_frames) every_unit = every_unit && f == static_cast<std::uint64_t>(s) * rate_hz;
    if (r.frames != expected || r.lost != 0 || r.corrupt != 0 || !every_unit) {
      std::printf("  FRAME ACCOUNTING FAILED: received %llu of %llu, lost %llu, corrupt %llu\n",
                  static_cast<unsigned long long>(r.frames), static_cast<unsigned long long>(expected),
                  static_cast<unsigned long long>(r.lost), static_cast<unsigned long long>(r.corrupt));
      std::filesystem::remove_all(dir);
      return 1;
    }
  }
  std::printf("\nCPU/sim. s: reader-thread CPU time per simulated second of traffic (100%% = one core).\n");
  std::printf("every frame received and accounted for: 0 lost, 0 corrupt.\n");
  std::filesystem::remove_all(dir);
  return 0;
}
