// Benchmark: fogctl's start-up (issue 30): the whole process of `fogctl --version` and of
// `fogctl fit` on a short run, against /bin/true (the floor of any process) and fogctl-fleet
// --version (the same CLI with the PostgreSQL client linked: what every fogctl command paid
// before the fleet commands moved out). Target: `fogctl --version` under 8 ms.
// Each command runs --runs times, the commands interleaved so that they share the machine's
// load; prints the minimum and median wall time and the median CPU time (user + system).
//   bench_fogctl_startup [--runs N] [--bin DIR] [--before FOGCTL]
// --bin: where fogctl and fogctl-fleet are (default: this benchmark's folder, build/bin);
// --before: another fogctl to time beside (e.g. one built before the split).
#include <fcntl.h>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

extern char** environ;

namespace {

struct Sample {
  double wall_ms = 0, cpu_ms = 0;
  int code = -1;
};

// Runs argv with stdout and stderr to /dev/null.
Sample run(const std::vector<std::string>& argv) {
  std::vector<char*> args;
  for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_addopen(&fa, 1, "/dev/null", O_WRONLY, 0);
  posix_spawn_file_actions_addopen(&fa, 2, "/dev/null", O_WRONLY, 0);
  const auto t0 = std::chrono::steady_clock::now();
  pid_t pid = 0;
  Sample s;
  if (posix_spawn(&pid, args[0], &fa, nullptr, args.data(), environ) != 0) return s;
  int status = 0;
  rusage ru{};
  wait4(pid, &status, 0, &ru);
  s.wall_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  s.cpu_ms = static_cast<double>(ru.ru_utime.tv_sec + ru.ru_stime.tv_sec) * 1e3 +
             static_cast<double>(ru.ru_utime.tv_usec + ru.ru_stime.tv_usec) * 1e-3;
  s.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  posix_spawn_file_actions_destroy(&fa);
  return s;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
  int runs = 50;
  std::filesystem::path bin = std::filesystem::absolute(argv[0]).parent_path();
  std::string before;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--runs" && i + 1 < argc) runs = std::atoi(argv[++i]);
    else if (a == "--bin" && i + 1 < argc) bin = argv[++i];
    else if (a == "--before" && i + 1 < argc) before = argv[++i];
    else {
      std::fprintf(stderr, "usage: bench_fogctl_startup [--runs N] [--bin DIR] [--before FOGCTL]\n");
      return 2;
    }
  }
  const std::string fogctl = (bin / "fogctl").string(), fleet = (bin / "fogctl-fleet").string();
  for (const auto& exe : {fogctl, fleet})
    if (!std::filesystem::exists(exe)) {
      std::fprintf(stderr, "bench_fogctl_startup: %s: no such file (build fogctl and fogctl-fleet)\n", exe.c_str());
      return 2;
    }
  // A short run to fit: exp1 simulated once (the fit's arithmetic is small beside start-up).
  char tmpl[] = "/tmp/fogctl-startup-XXXXXX";
  if (!mkdtemp(tmpl)) return 2;
  const std::filesystem::path dir = tmpl;
  const std::string csv = (dir / "exp1.csv").string(), model = (dir / "model.json").string();
  if (run({fogctl, "simulate", "--profile", "exp1", "--seed", "1", "-o", csv}).code != 0) {
    std::fprintf(stderr, "bench_fogctl_startup: fogctl simulate failed\n");
    return 2;
  }
  struct Command {
    std::string name;
    std::vector<std::string> argv;
    std::vector<Sample> samples;
  };
  std::vector<Command> commands = {
      {"/bin/true (a process's floor)", {"/bin/true"}, {}},
      {"fogctl --version", {fogctl, "--version"}, {}},
      {"fogctl-fleet --version (libpq linked)", {fleet, "--version"}, {}},
      {"fogctl fit exp1.csv (10,800 samples)", {fogctl, "fit", csv, "-o", model}, {}},
  };
  if (!before.empty()) {
    commands.push_back({"before: fogctl --version", {before, "--version"}, {}});
    commands.push_back({"before: fogctl fit exp1.csv", {before, "fit", csv, "-o", model}, {}});
  }
  for (auto& c : commands) run(c.argv);  // warm the page cache
  for (int r = 0; r < runs; ++r)
    for (auto& c : commands) c.samples.push_back(run(c.argv));
  std::printf("%-44s %9s %11s %10s  (%d runs each, interleaved)\n", "command", "min ms", "median ms", "cpu ms", runs);
  int failed = 0;
  for (const auto& c : commands) {
    std::vector<double> wall, cpu;
    for (const auto& s : c.samples) {
      wall.push_back(s.wall_ms);
      cpu.push_back(s.cpu_ms);
      failed += s.code != 0;
    }
    std::printf("%-44s %9.2f %11.2f %10.2f\n", c.name.c_str(), *std::min_element(wall.begin(), wall.end()),
                median(wall), median(cpu));
  }
  std::filesystem::remove_all(dir);
  if (failed) std::fprintf(stderr, "bench_fogctl_startup: %d runs exited non-zero\n", failed);
  return failed ? 1 : 0;
}
