// One fogbenchd per store and per socket path (docs/daemon.md, "One daemon per store"). The
// store is claimed by an exclusive flock on `<store>.lock`, held for the process's lifetime, with
// the holder's pid written in it; a socket path is taken over only when nothing answers on it,
// and on exit removed only if it is still the socket this process bound. No Asio here: plain
// POSIX calls, tested in tests/daemon/instance_test.cpp.
#pragma once

#include <sys/types.h>

#include <expected>
#include <filesystem>
#include <string>

namespace fogbench::daemon {

// The files the daemon creates: the store and its lock (storage's OpenOptions::file_mode is the
// same), and the folders it makes for the socket. Set with fchmod/chmod, never from the umask.
inline constexpr ::mode_t kStoreFileMode = 0640;
inline constexpr ::mode_t kSocketDirMode = 0750;

struct ClaimError {
  std::string message;
  bool held_by_other = false;  // another live daemon: fogbenchd exits 2 (else 1)
};

// An exclusive lock on `<store>.lock`: released when the object (its descriptor) goes.
class StoreLock {
 public:
  // Takes the lock without waiting; a lock held by another process is refused with its pid.
  static std::expected<StoreLock, ClaimError> acquire(const std::filesystem::path& store_path);
  static std::filesystem::path lock_path(const std::filesystem::path& store_path);

  StoreLock(StoreLock&& o) noexcept : fd_(o.fd_), path_(std::move(o.path_)) { o.fd_ = -1; }
  StoreLock& operator=(StoreLock&& o) noexcept;
  StoreLock(const StoreLock&) = delete;
  StoreLock& operator=(const StoreLock&) = delete;
  ~StoreLock();

  const std::filesystem::path& path() const { return path_; }

 private:
  StoreLock(int fd, std::filesystem::path path) : fd_(fd), path_(std::move(path)) {}
  int fd_ = -1;
  std::filesystem::path path_;
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
