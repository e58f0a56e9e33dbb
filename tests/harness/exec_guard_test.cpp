// The check that keeps the `process` labels honest (tests/main.cpp): a test that is not labelled
// `process` runs with FOGBENCH_TEST_NO_EXEC=1, and then no program may be executed. Asked to
// execute a file that does not exist, the kernel answers ENOENT; under the filter it refuses
// first, with EPERM, so this test cannot replace itself with another program however it fails.
#include <catch2/catch.hpp>

#include <fcntl.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <string_view>

TEST_CASE("harness: a test not labelled process can execute nothing (FOGBENCH_TEST_NO_EXEC)") {
  const char* flag = std::getenv("FOGBENCH_TEST_NO_EXEC");
  // CTest sets it on this test (tests/CMakeLists.txt); run by hand without it, the check cannot
  // run, and a check that cannot run fails rather than passing with nothing checked.
  if (!flag || std::string_view(flag) != "1") FAIL("FOGBENCH_TEST_NO_EXEC is not 1: run it through CTest (or with it set) to check the filter");
  char path[] = "/nonexistent/fogbench-exec-guard";
  char* argv[] = {path, nullptr};
  char* envp[] = {nullptr};
  errno = 0;
  const long r = ::syscall(SYS_execve, path, argv, envp);
  const int err = errno;
  CHECK(r == -1);
  CHECK(err == EPERM);  // ENOENT: the filter is not installed, and a process test would pass unnoticed
  errno = 0;
  const long r2 = ::syscall(SYS_execveat, AT_FDCWD, path, argv, envp, 0);
  CHECK(r2 == -1);
  CHECK(errno == EPERM);
}
