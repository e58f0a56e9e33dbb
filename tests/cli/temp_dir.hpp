// What fogctl's tests share whether or not they start a program: a temporary directory per test
// case and a file's bytes. tests/cli/fogctl_process.hpp adds running programs on top; this
// header starts nothing, so a test including only it stays a quick test (tests/CMakeLists.txt).
#pragma once

#include <unistd.h>

#include <atomic>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

namespace fogbench::cli::testing {

// A fresh directory per test case (its name says which test made it and the process), removed
// at the end.
struct Dir {
  std::filesystem::path path;
  explicit Dir(const std::string& what = "fogctl") {
    static std::atomic<int> counter{0};
    path = std::filesystem::temp_directory_path() /
           (what + "-" + std::to_string(::getpid()) + "-" + std::to_string(counter++));
    std::filesystem::remove_all(path);
    std::filesystem::create_directories(path);
  }
  ~Dir() {
    std::error_code ec;
    std::filesystem::remove_all(path, ec);
  }
  Dir(const Dir&) = delete;
  Dir& operator=(const Dir&) = delete;
  // The path of `name` inside the directory.
  std::string file(const std::string& name) const { return (path / name).string(); }
  // Writes `text` to `name` inside the directory (bytes as given) and returns its path.
  std::string write(const std::string& name, const std::string& text) const {
    std::ofstream(path / name, std::ios::binary) << text;
    return file(name);
  }
};

inline std::string slurp(const std::string& p) {
  std::ifstream f(p, std::ios::binary);
  std::stringstream s;
  s << f.rdbuf();
  return s.str();
}

}  // namespace fogbench::cli::testing
