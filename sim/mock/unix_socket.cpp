// See unix_socket.hpp.
#include "unix_socket.hpp"

#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

namespace fogbench::mock {

std::string errno_text(int err) { return std::strerror(err); }

namespace {

// Makes `path` free for a listening unix socket: a stale socket nobody listens on is removed;
// a live one or any other file is an error.
std::expected<void, std::string> free_unix_path(const std::string& path, int type) {
  struct stat st {};
  if (::lstat(path.c_str(), &st) != 0) return {};
  if (!S_ISSOCK(st.st_mode)) return std::unexpected(path + ": exists and is not a socket");
  const int probe = ::socket(AF_UNIX, type | SOCK_CLOEXEC, 0);
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  std::memcpy(addr.sun_path, path.c_str(), path.size() + 1);
  const bool live = ::connect(probe, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0;
  ::close(probe);
  if (live) return std::unexpected(path + ": another process is listening there");
  ::unlink(path.c_str());
  return {};
}

}  // namespace

std::expected<int, std::string> listen_unix(const std::string& path, int type) {
  sockaddr_un addr{};
  if (path.empty() || path.size() >= sizeof addr.sun_path) {
    return std::unexpected(path + ": a unix socket path must be 1.." + std::to_string(sizeof addr.sun_path - 1) + " characters");
  }
  if (auto ok = free_unix_path(path, type); !ok) return std::unexpected(ok.error());
  addr.sun_family = AF_UNIX;
  std::memcpy(addr.sun_path, path.c_str(), path.size() + 1);
  const int fd = ::socket(AF_UNIX, type | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
  if (fd < 0) return std::unexpected(path + ": socket: " + errno_text(errno));
  if (::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0 || ::listen(fd, 16) != 0) {
    const int err = errno;
    ::close(fd);
    return std::unexpected(path + ": " + errno_text(err));
  }
  return fd;
}

}  // namespace fogbench::mock
