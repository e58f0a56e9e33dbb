// The one Catch2 main shared by every test executable.
//
// With FOGBENCH_TEST_NO_EXEC=1 in its environment (CTest sets it on every test that is not
// labelled `process`: tests/CMakeLists.txt) the executable may start no program: before any
// test runs, a seccomp filter makes execve and execveat fail with EPERM, in this process and in
// any child it forks. A quick test that starts fogbenchd, fogbench-sim, fogctl, PostgreSQL,
// Chromium, a compiler or a shell therefore fails instead of passing slowly: its source belongs
// with the `process` tests (tests/CMakeLists.txt sorts sources by what they include and call).
#define CATCH_CONFIG_RUNNER
#include <catch2/catch.hpp>

#include <linux/audit.h>
#include <linux/filter.h>
#include <linux/seccomp.h>
#include <sys/prctl.h>
#include <sys/syscall.h>

#include <cerrno>
#include <cstddef>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <iterator>
#include <string_view>

namespace {

bool forbid_exec() {
#if defined(__x86_64__)
  constexpr unsigned kArch = AUDIT_ARCH_X86_64;
#elif defined(__aarch64__)
  constexpr unsigned kArch = AUDIT_ARCH_AARCH64;
#else
  std::fprintf(stderr, "FOGBENCH_TEST_NO_EXEC: no seccomp filter for this architecture\n");
  return false;
#endif
  sock_filter filter[] = {
      BPF_STMT(BPF_LD | BPF_W | BPF_ABS, offsetof(seccomp_data, arch)),
      BPF_JUMP(BPF_JMP | BPF_JEQ | BPF_K, kArch, 1, 0),
      BPF_STMT(BPF_RET | BPF_K, SECCOMP_RET_ERRNO | (EPERM & SECCOMP_RET_DATA)),  // another ABI: refused too
      BPF_STMT(BPF_LD | BPF_W | BPF_ABS, offsetof(seccomp_data, nr)),
      BPF_JUMP(BPF_JMP | BPF_JEQ | BPF_K, __NR_execve, 2, 0),
      BPF_JUMP(BPF_JMP | BPF_JEQ | BPF_K, __NR_execveat, 1, 0),
      BPF_STMT(BPF_RET | BPF_K, SECCOMP_RET_ALLOW),
      BPF_STMT(BPF_RET | BPF_K, SECCOMP_RET_ERRNO | (EPERM & SECCOMP_RET_DATA)),
  };
  sock_fprog prog{static_cast<unsigned short>(std::size(filter)), filter};
  // Unprivileged filters need no_new_privs; it only stops set-uid programs gaining rights on exec.
  if (::prctl(PR_SET_NO_NEW_PRIVS, 1, 0, 0, 0) != 0 || ::prctl(PR_SET_SECCOMP, SECCOMP_MODE_FILTER, &prog) != 0) {
    std::fprintf(stderr, "FOGBENCH_TEST_NO_EXEC: cannot install the seccomp filter: %s\n", std::strerror(errno));
    return false;
  }
  return true;
}

}  // namespace

int main(int argc, char* argv[]) {
  if (const char* v = std::getenv("FOGBENCH_TEST_NO_EXEC"); v && std::string_view(v) == "1" && !forbid_exec())
    return 2;  // the check of the labels would not hold: fail rather than pass unchecked
  return Catch::Session().run(argc, argv);
}
