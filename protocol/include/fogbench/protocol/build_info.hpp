// Which fogbench this is: the version and the git commit it was built from, found when the
// build was configured (protocol/CMakeLists.txt; "unknown" outside a git checkout). Every run's
// identity and every certificate carries them (docs/daemon.md, "Run identity").
#pragma once

#include <string_view>

namespace fogbench::protocol {

struct BuildInfo {
  std::string_view version;       // the project's version, e.g. "0.1.0"
  std::string_view git_hash;      // the full commit hash, or "unknown"
  std::string_view git_describe;  // `git describe --always --dirty` ("-dirty": uncommitted changes), or "unknown"
};

const BuildInfo& build_info();

}  // namespace fogbench::protocol
