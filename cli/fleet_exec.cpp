// fogctl's side of the fleet commands (fleet.hpp): it executes fogctl-fleet, which links the
// PostgreSQL client, so that fogctl itself never loads libpq (issue 30).
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <ostream>

#include "fleet.hpp"

#ifndef FOGBENCH_FLEET_FROM_BINDIR
#define FOGBENCH_FLEET_FROM_BINDIR "../libexec/fogbench"
#endif

namespace fogbench::cli {

std::vector<std::string> fleet_program_candidates(const std::string& self) {
  const std::filesystem::path dir = std::filesystem::path(self).parent_path();
  return {(dir / "fogctl-fleet").string(),
          (dir / FOGBENCH_FLEET_FROM_BINDIR / "fogctl-fleet").lexically_normal().string()};
}

int run_fleet_program(char** argv, std::ostream& err) {
  std::error_code ec;
  const auto self = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (ec) {
    err << "fogctl fleet: cannot find the fleet program fogctl-fleet: /proc/self/exe: " << ec.message() << "\n";
    return kExitError;
  }
  std::vector<char*> args;
  for (char** a = argv; *a; ++a) args.push_back(*a);
  args.push_back(nullptr);
  std::string tried;
  for (const auto& path : fleet_program_candidates(self.string())) {
    args[0] = const_cast<char*>(path.c_str());
    execv(path.c_str(), args.data());  // returns only on failure
    tried += "\n  " + path + ": " + std::strerror(errno);
  }
  err << "fogctl fleet: the fleet commands run in fogctl-fleet (it links the PostgreSQL client, libpq), "
         "which cannot be executed:"
      << tried << "\n(install it with fogctl: `cmake --install`, component runtime; docs/cli.md \"fogctl fleet\")\n";
  return kExitError;
}

}  // namespace fogbench::cli
