// One fogbenchd per store and per socket path (docs/daemon.md, "One daemon per store"). The
// store is claimed by storage's StoreLock (an exclusive flock on `<store>.lock`, held for the
// process's lifetime, with the holder's pid written in it); a socket path is taken over only
// when nothing answers on it, and on exit removed only if it is still the socket this process
// bound. No Asio here: plain POSIX calls, tested in tests/daemon/instance_test.cpp.
#pragma once

#include <sys/types.h>

#include <expected>
#include <filesystem>
#include <string>

#include "fogbench/storage/lock.hpp"

namespace fogbench::daemon {

// The store's lock and the store file's mode live in storage (lock.hpp): `fogctl store vacuum`
// takes the same lock. The folders the daemon makes for the socket get kSocketDirMode, set with
// chmod, never from the umask.
using storage::kStoreFileMode;
using storage::StoreLock;
inline constexpr ::mode_t kSocketDirMode = 0750;

struct ClaimError {
  std::string message;
  bool held_by_other = false;  // another live daemon: fogbenchd exits 2 (else 1)
};

// Creates the missing folders of `dir` with mode kSocketDirMode (each one made here is chmod-ed,
// so the umask does not matter; folders that exist are left as they are).
std::expected<void, std::string> make_dirs(const std::filesystem::path& dir, ::mode_t mode = kSocketDirMode);

// Before binding a unix socket at `path`: refused (held_by_other) when a process accepts
// connections on it; a stale socket file (nothing listening) is removed; anything that is not a
// socket is refused, never deleted.
std::expected<void, ClaimError> clear_stale_socket(const std::filesystem::path& path);

// The identity of the socket file this process bound, to remove only that one on exit.
struct SocketFileId {
  ::dev_t dev = 0;
  ::ino_t ino = 0;
  bool valid = false;
};
SocketFileId socket_file_id(const std::filesystem::path& path);
// Removes `path` if it is still the file `id` names; true when removed.
bool remove_if_ours(const std::filesystem::path& path, const SocketFileId& id);

}  // namespace fogbench::daemon
