// The store's owner: an exclusive flock on `<store>.lock`, held by fogbenchd for its lifetime
// (docs/daemon.md, "One daemon per store") and by `fogctl store vacuum` while it rewrites the
// file (docs/storage.md, "Retention"), so neither starts while the other holds the store. The
// holder's pid is written in the file, for the refusal's message and for people.
#pragma once

#include <sys/types.h>

#include <expected>
#include <filesystem>
#include <string>

namespace fogbench::storage {

// The mode of the store and its lock file (OpenOptions::file_mode is set to the same by the
// daemon). Set with fchmod, never from the umask.
inline constexpr ::mode_t kStoreFileMode = 0640;

struct LockError {
  std::string message;
  bool held_by_other = false;  // another live process holds it (its pid is in the message)
};

// An exclusive lock on `<store>.lock`: released when the object (its descriptor) goes.
class StoreLock {
 public:
  // Takes the lock without waiting; a lock held by another process is refused with its pid.
  static std::expected<StoreLock, LockError> acquire(const std::filesystem::path& store_path);
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

}  // namespace fogbench::storage
