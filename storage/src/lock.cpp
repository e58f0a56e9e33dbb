// The store's lock file (lock.hpp): one owner of a store at a time, fogbenchd or
// `fogctl store vacuum`.
#include "fogbench/storage/lock.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>

namespace fogbench::storage {

namespace {
std::string errno_text(int e) { return std::strerror(e); }

// The pid a lock file names, or 0 when it holds none.
long read_pid(int fd) {
  char buf[32] = {};
  const ssize_t n = ::pread(fd, buf, sizeof buf - 1, 0);
  if (n <= 0) return 0;
  return std::strtol(buf, nullptr, 10);
}

// What the holder is (fogbenchd, fogctl), from /proc/PID/comm; "another process" when unknown.
std::string holder_name(long pid) {
  if (pid <= 0) return "another process";
  std::FILE* f = std::fopen(("/proc/" + std::to_string(pid) + "/comm").c_str(), "r");
  if (!f) return "another process";
  char buf[32] = {};
  const bool got = std::fgets(buf, sizeof buf, f) != nullptr;
  std::fclose(f);
  std::string name = got ? buf : "";
  while (!name.empty() && (name.back() == '\n' || name.back() == ' ')) name.pop_back();
  return name.empty() ? "another process" : name;
}
}  // namespace

std::filesystem::path StoreLock::lock_path(const std::filesystem::path& store_path) {
  return std::filesystem::path(store_path.string() + ".lock");
}

std::expected<StoreLock, LockError> StoreLock::acquire(const std::filesystem::path& store_path) {
  const auto path = lock_path(store_path);
  const int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW, kStoreFileMode);
  if (fd < 0) return std::unexpected(LockError{"cannot open the store's lock " + path.string() + ": " + errno_text(errno)});
  // flock, not fcntl: an fcntl lock is dropped when this process closes *any* descriptor of the
  // file, and belongs to the process rather than to this descriptor (so two opens in one process,
  // as the tests do, would not exclude each other).
  if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
    const int e = errno;
    const long pid = read_pid(fd);
    ::close(fd);
    if (e == EWOULDBLOCK)
      return std::unexpected(LockError{"the store is in use by " + holder_name(pid) + " (pid " +
                                            (pid > 0 ? std::to_string(pid) : std::string("unknown")) + ", lock " +
                                            path.string() + ")",
                                        true});
    return std::unexpected(LockError{"cannot lock " + path.string() + ": " + errno_text(e)});
  }
  // Ours now. The mode whatever the umask (and whoever made the file before).
  struct stat st{};
  if (::fstat(fd, &st) == 0 && st.st_uid == ::geteuid() && (st.st_mode & 07777) != kStoreFileMode)
    (void)::fchmod(fd, kStoreFileMode);
  const std::string pid = std::to_string(::getpid()) + "\n";
  if (::ftruncate(fd, 0) != 0 || ::pwrite(fd, pid.data(), pid.size(), 0) != static_cast<ssize_t>(pid.size())) {
    const int e = errno;
    ::close(fd);
    return std::unexpected(LockError{"cannot write the pid into " + path.string() + ": " + errno_text(e)});
  }
  return StoreLock(fd, path);
}

StoreLock& StoreLock::operator=(StoreLock&& o) noexcept {
  if (this != &o) {
    if (fd_ >= 0) ::close(fd_);
    fd_ = o.fd_;
    path_ = std::move(o.path_);
    o.fd_ = -1;
  }
  return *this;
}

StoreLock::~StoreLock() {
  // The file stays (removing it would race with a daemon starting now); closing unlocks it.
  if (fd_ >= 0) ::close(fd_);
}

}  // namespace fogbench::storage
