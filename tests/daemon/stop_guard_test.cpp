// The stop's last guard (daemon/src/stop_budget.hpp, docs/reliability.md "The stop's budget"): a
// stop still going when its budget is spent ends the process with status 1, naming the step it
// was stuck in, whatever that step waits on; a stop that ends in time disarms it and the process
// goes on. The guard's exit is the process's, so each case runs in a forked child that holds
// nothing but the guard (a child of a threaded test process may only do simple things: it does).
#include <sys/wait.h>
#include <unistd.h>

#include <catch2/catch.hpp>
#include <chrono>
#include <memory>
#include <string>

#include <spdlog/sinks/stdout_sinks.h>
#include <spdlog/spdlog.h>

#include "../../daemon/src/stop_budget.hpp"

using namespace fogbench::daemon;
using namespace std::chrono_literals;

namespace {

struct ChildEnd {
  int status = -1;     // the exit status, or -1 when the child did not exit normally
  std::string output;  // what the child wrote on the pipe (its log)
};

// Runs `body` in a forked child whose log goes to a pipe; the child exits 0 after body returns.
template <class Body>
ChildEnd in_child(Body body) {
  int fds[2];
  REQUIRE(::pipe(fds) == 0);
  const pid_t pid = ::fork();
  REQUIRE(pid >= 0);
  if (pid == 0) {
    ::close(fds[0]);
    ::dup2(fds[1], STDERR_FILENO);
    spdlog::set_default_logger(
        std::make_shared<spdlog::logger>("stop_guard_child", std::make_shared<spdlog::sinks::stderr_sink_st>()));
    body();
    std::_Exit(0);
  }
  ::close(fds[1]);
  ChildEnd end;
  char buf[4096];
  for (ssize_t n; (n = ::read(fds[0], buf, sizeof buf)) > 0;) end.output.append(buf, static_cast<std::size_t>(n));
  ::close(fds[0]);
  int st = 0;
  REQUIRE(::waitpid(pid, &st, 0) == pid);
  if (WIFEXITED(st)) end.status = WEXITSTATUS(st);
  return end;
}

}  // namespace

TEST_CASE("stop guard: a stop stuck in a step past its budget ends the process with status 1, naming the step") {
  const ChildEnd end = in_child([] {
    StopGuard guard;
    guard.arm(1s);
    guard.step("chamber to its safe setpoint");
    for (;;) ::pause();  // a device call that never returns
  });
  CHECK(end.status == 1);
  CHECK_THAT(end.output, Catch::Contains("the stop's budget of 1 s is spent in step 'chamber to its safe setpoint'") &&
                             Catch::Contains("exiting now (status 1)"));
}

TEST_CASE("stop guard: a stop that ends within its budget disarms the guard, and the process goes on") {
  const ChildEnd end = in_child([] {
    StopGuard guard;
    guard.arm(60s);
    guard.step("plant link");
    guard.step("sample writer");  // logs how long the plant link took
    guard.disarm();
  });
  CHECK(end.status == 0);
  CHECK_THAT(end.output, Catch::Contains("stopping: plant link took"));
  CHECK_THAT(end.output, !Catch::Contains("budget"));
}
