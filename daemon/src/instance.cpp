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

}  // namespace

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
