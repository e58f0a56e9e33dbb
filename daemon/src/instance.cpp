// One fogbenchd per store and per socket path: the store's lock file and the socket file's
// take-over and removal (instance.hpp).
#include "fogbench/daemon/instance.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

namespace fogbench::daemon {

namespace {
std::string errno_text(int e) { return std::strerror(e); }

// The pid a lock file names, or 0 when it holds none.
long read_pid(int fd) {
  char buf[32] = {};
  const ssize_t n = ::pread(fd, buf, sizeof buf - 1, 0);
  if (n <= 0) return 0;
  return std::strtol(buf, nullptr, 10);
}
}  // namespace

std::filesystem::path StoreLock::lock_path(const std::filesystem::path& store_path) {
  return std::filesystem::path(store_path.string() + ".lock");
}

std::expected<StoreLock, ClaimError> StoreLock::acquire(const std::filesystem::path& store_path) {
  const auto path = lock_path(store_path);
  const int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW, kStoreFileMode);
  if (fd < 0) return std::unexpected(ClaimError{"cannot open the store's lock " + path.string() + ": " + errno_text(errno)});
  // flock, not fcntl: an fcntl lock is dropped when this process closes *any* descriptor of the
  // file, and belongs to the process rather than to this descriptor (so two opens in one process,
  // as the tests do, would not exclude each other).
  if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
    const int e = errno;
    const long pid = read_pid(fd);
    ::close(fd);
    if (e == EWOULDBLOCK)
      return std::unexpected(ClaimError{"the store is in use by another fogbenchd (pid " +
                                            (pid > 0 ? std::to_string(pid) : std::string("unknown")) + ", lock " +
                                            path.string() + ")",
                                        true});
    return std::unexpected(ClaimError{"cannot lock " + path.string() + ": " + errno_text(e)});
  }
  // Ours now. The mode whatever the umask (and whoever made the file before).
  struct stat st{};
  if (::fstat(fd, &st) == 0 && st.st_uid == ::geteuid() && (st.st_mode & 07777) != kStoreFileMode)
    (void)::fchmod(fd, kStoreFileMode);
  const std::string pid = std::to_string(::getpid()) + "\n";
  if (::ftruncate(fd, 0) != 0 || ::pwrite(fd, pid.data(), pid.size(), 0) != static_cast<ssize_t>(pid.size())) {
    const int e = errno;
    ::close(fd);
    return std::unexpected(ClaimError{"cannot write the pid into " + path.string() + ": " + errno_text(e)});
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

std::expected<void, std::string> make_dirs(const std::filesystem::path& dir, ::mode_t mode) {
  if (dir.empty()) return {};
  std::filesystem::path p;
  for (const auto& part : dir) {
    p /= part;
    if (::mkdir(p.c_str(), mode) == 0) {
      if (::chmod(p.c_str(), mode) != 0) return std::unexpected("chmod " + p.string() + ": " + errno_text(errno));
    } else if (errno != EEXIST) {
      return std::unexpected("mkdir " + p.string() + ": " + errno_text(errno));
    }
  }
  return {};
}

std::expected<void, ClaimError> clear_stale_socket(const std::filesystem::path& path) {
  struct stat st{};
  if (::lstat(path.c_str(), &st) != 0) {
    if (errno == ENOENT) return {};
    return std::unexpected(ClaimError{"socket " + path.string() + ": " + errno_text(errno)});
  }
  if (!S_ISSOCK(st.st_mode))
    return std::unexpected(ClaimError{"socket " + path.string() + ": exists and is not a socket; not removed"});
  sockaddr_un a{};
  a.sun_family = AF_UNIX;
  if (path.string().size() >= sizeof a.sun_path)
    return std::unexpected(ClaimError{"socket " + path.string() + ": path too long"});
  std::strncpy(a.sun_path, path.c_str(), sizeof a.sun_path - 1);
  const int fd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return std::unexpected(ClaimError{"socket: " + errno_text(errno)});
  const int rc = ::connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a);
  const int e = errno;
  ::close(fd);
  // A full backlog (EAGAIN) is a live daemon too: only "nobody listens" makes the file stale.
  if (rc == 0 || e == EAGAIN)
    return std::unexpected(ClaimError{"socket " + path.string() + ": another process answers on it (another fogbenchd?)", true});
  if (e != ECONNREFUSED && e != ENOENT)
    return std::unexpected(ClaimError{"socket " + path.string() + ": probing it: " + errno_text(e)});
  if (::unlink(path.c_str()) != 0 && errno != ENOENT)
    return std::unexpected(ClaimError{"socket " + path.string() + ": removing the stale socket: " + errno_text(errno)});
  return {};
}

SocketFileId socket_file_id(const std::filesystem::path& path) {
  struct stat st{};
  if (::lstat(path.c_str(), &st) != 0) return {};
  return {st.st_dev, st.st_ino, true};
}

bool remove_if_ours(const std::filesystem::path& path, const SocketFileId& id) {
  if (!id.valid) return false;
  const SocketFileId now = socket_file_id(path);
  if (!now.valid || now.dev != id.dev || now.ino != id.ino) return false;
  return ::unlink(path.c_str()) == 0;
}

}  // namespace fogbench::daemon
