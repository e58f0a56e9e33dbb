// What the tests that run the built fogctl (and its peers) share: temp_dir.hpp's directory per
// test case and a file's bytes, and a program run with its exit code, stdout and stderr (to files:
// not a terminal). Including this header makes a test a `process` test (tests/CMakeLists.txt).
#pragma once

#include <catch2/catch.hpp>
#include "temp_dir.hpp"
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

namespace fogbench::cli::testing {

struct Ran {
  int code = -1;
  std::string out, err;
};

// `exe args` (shell words) with `env` (NAME=value words, or `-u NAME`) before it, stdin empty.
inline Ran run(const Dir& d, const std::string& exe, const std::string& args, const std::string& env = "") {
  REQUIRE(std::filesystem::exists(exe));
  const std::string out = d.file("out.txt"), err = d.file("err.txt");
  const std::string cmd = "env " + env + " '" + exe + "' " + args + " >'" + out + "' 2>'" + err + "' </dev/null";
  const int s = std::system(cmd.c_str());
  return {WIFEXITED(s) ? WEXITSTATUS(s) : -1, slurp(out), slurp(err)};
}

// The built fogctl, without a progress mode from the test's own environment.
inline Ran fogctl(const Dir& d, const std::string& args, const std::string& env = "") {
  return run(d, std::string(FOGBENCH_BIN_DIR) + "/fogctl", args, "-u FOGCTL_PROGRESS " + env);
}

}  // namespace fogbench::cli::testing
