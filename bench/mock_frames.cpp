// bench_mock_frames: how fast the mock bench (fogbench-sim) can serve gyro frames. Starts the
// real executable (next to this one in build/bin) for several unit counts and time scales, reads
// its CAN socket with the drivers' GyroBus for a few wall seconds, and reports the frames
// delivered against those due, the frames lost, the bench's CPU and its clock against K.
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

#include "fogbench/drivers/gyro_bus.hpp"

extern char** environ;

namespace {

using nlohmann::json;
using Clock = std::chrono::steady_clock;

std::string read_line(int fd) {
  std::string line;
  char c = 0;
  pollfd p{fd, POLLIN, 0};
  while (::poll(&p, 1, 20000) > 0 && ::read(fd, &c, 1) == 1 && c != '\n') line += c;
  return line;
}

json control(const std::string& path, const json& request) {
  const int fd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  std::strncpy(addr.sun_path, path.c_str(), sizeof addr.sun_path - 1);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) return {};
  const auto line = request.dump() + "\n";
  [[maybe_unused]] auto n = ::send(fd, line.data(), line.size(), MSG_NOSIGNAL);
  const auto reply = read_line(fd);
  ::close(fd);
  return reply.empty() ? json{} : json::parse(reply);
}

// utime + stime of a process, seconds.
double cpu_s(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/stat");
  std::string s((std::istreambuf_iterator<char>(in)), {});
  const auto close = s.rfind(')');
  std::vector<std::string> f;
  std::size_t pos = close + 2;
  while (pos < s.size()) {
    const auto sp = s.find(' ', pos);
    f.push_back(s.substr(pos, sp - pos));
    if (sp == std::string::npos) break;
    pos = sp + 1;
  }
  // Fields 14 and 15 of stat (utime, stime) are f[11], f[12] after the name.
  return (std::stod(f[11]) + std::stod(f[12])) / static_cast<double>(::sysconf(_SC_CLK_TCK));
}

void run_case(const std::string& bin, int units, double k, int rate_hz, double seconds) {
  char tmpl[] = "/tmp/fogbench-benchmock-XXXXXX";
  if (::mkdtemp(tmpl) == nullptr) return;
  const std::string dir = tmpl;
  std::vector<std::string> args = {bin, "--modbus-port", "0", "--thermistor-port", "0",
                                   "--can-socket", dir + "/can.sock", "--control", dir + "/control.sock",
                                   "--units", std::to_string(units), "--time-scale", std::to_string(k),
                                   "--frame-rate-hz", std::to_string(rate_hz), "--log-level", "error"};
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  int out[2];
  if (::pipe2(out, O_CLOEXEC) != 0) return;
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, out[1], STDOUT_FILENO);
  pid_t pid = -1;
  const int rc = ::posix_spawn(&pid, argv[0], &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  ::close(out[1]);
  const auto line = rc == 0 ? read_line(out[0]) : std::string();
  if (line.empty()) {
    std::printf("%d units, K=%g: fogbench-sim did not start (%s)\n", units, k, bin.c_str());
    return;
  }
  const json ready = json::parse(line);
  std::vector<fogbench::drivers::GyroChannelConfig> gyros;
  for (const auto& u : ready["drivers_config"]["units"]) {
    auto g = fogbench::drivers::parse_gyro_channel(u["gyro"], "gyro");
    if (g) gyros.push_back(*g);
  }
  auto bus = fogbench::drivers::GyroBus::open({"unix:" + dir + "/can.sock"}, gyros);
  if (!bus) {
    std::printf("GyroBus: %s\n", bus.error().to_string().c_str());
    return;
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(200));  // accepted by the bench
  std::vector<can_frame> buf;
  while (true) {  // what queued meanwhile is not part of the measurement
    auto n = bus->read_frames(buf);
    if (!n || *n == 0) break;
  }
  bus->close_samples();
  const double sim0 = control(dir + "/control.sock", {{"cmd", "status"}}).value("time_s", 0.0);
  const double cpu0 = cpu_s(pid);
  const auto t0 = Clock::now();
  std::uint64_t frames = 0, lost = 0;
  while (Clock::now() - t0 < std::chrono::duration<double>(seconds)) {
    pollfd p{bus->fd(), POLLIN, 0};
    ::poll(&p, 1, 10);
    if (!bus->read_frames(buf)) break;
    const auto s = bus->close_samples();
    for (const auto& g : s.units) {
      frames += g.frames;
      lost += g.frames_lost;
    }
  }
  const double wall = std::chrono::duration<double>(Clock::now() - t0).count();
  const double cpu = cpu_s(pid) - cpu0;
  const json st = control(dir + "/control.sock", {{"cmd", "status"}});
  const double sim1 = st.value("time_s", 0.0);
  std::printf("%2d units  K=%-6g %4d Hz | due %9.0f frames/s  got %9.0f  lost %7llu  bench dropped %7llu | bench CPU %5.1f%% | clock %.3f x K\n",
              units, k, rate_hz, units * rate_hz * k, static_cast<double>(frames) / wall,
              static_cast<unsigned long long>(lost), static_cast<unsigned long long>(st.value("can_frames_dropped", 0ull)),
              100.0 * cpu / wall, (sim1 - sim0) / (k * wall));
  ::kill(pid, SIGTERM);
  ::waitpid(pid, nullptr, 0);
  ::close(out[0]);
  std::filesystem::remove_all(dir);
}

}  // namespace

int main(int argc, char** argv) {
  // fogbench-sim sits next to this benchmark (build/bin); a path may be given instead.
  const std::string bin = argc > 1 ? argv[1]
                                   : (std::filesystem::read_symlink("/proc/self/exe").parent_path() / "fogbench-sim").string();
  std::printf("mock bench frame delivery to one GyroBus reader (3 s each); the physics alone costs\n"
              "about 10 us of CPU per unit and simulated second (8 units: K up to ~10,000 on a free core)\n");
  for (auto [units, k] : {std::pair{2, 200.0}, std::pair{8, 200.0}, std::pair{8, 1000.0}, std::pair{8, 5000.0}}) {
    run_case(bin, units, k, 100, 3.0);
  }
  return 0;
}
