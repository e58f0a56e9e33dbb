// The simulated clock's client; see sim_clock.hpp.
#include "sim_clock.hpp"

#include <sys/socket.h>
#include <sys/time.h>
#include <sys/un.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include <nlohmann/json.hpp>

namespace fogbench::daemon {

SimClock::SimClock(std::filesystem::path control, std::chrono::milliseconds timeout)
    : control_(std::move(control)), timeout_(timeout) {}

SimClock::~SimClock() { disconnect(); }

void SimClock::disconnect() {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
  in_.clear();
}

std::expected<void, std::string> SimClock::connect() {
  const std::string path = control_.string();
  sockaddr_un addr{};
  if (path.size() >= sizeof addr.sun_path) return std::unexpected(path + ": path too long for a unix socket");
  addr.sun_family = AF_UNIX;
  std::memcpy(addr.sun_path, path.c_str(), path.size() + 1);
  const int fd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return std::unexpected(std::string("socket: ") + std::strerror(errno));
  timeval tv{};
  tv.tv_sec = static_cast<time_t>(timeout_.count() / 1000);
  tv.tv_usec = static_cast<suseconds_t>((timeout_.count() % 1000) * 1000);
  ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  ::setsockopt(fd, SOL_SOCKET, SO_SNDTIMEO, &tv, sizeof tv);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) {
    const int err = errno;
    ::close(fd);
    return std::unexpected(path + ": connect: " + std::strerror(err));
  }
  fd_ = fd;
  return {};
}

std::expected<double, std::string> SimClock::advance(std::int64_t seconds) {
  if (fd_ < 0)
    if (auto ok = connect(); !ok) return std::unexpected(ok.error());
  auto fail = [&](const std::string& why) {
    disconnect();
    return std::unexpected(control_.string() + ": " + why);
  };
  const std::string request = nlohmann::json{{"cmd", "advance"}, {"seconds", seconds}}.dump() + "\n";
  for (std::size_t sent = 0; sent < request.size();) {
    const auto n = ::send(fd_, request.data() + sent, request.size() - sent, MSG_NOSIGNAL);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return fail(std::string("send: ") + std::strerror(errno));
    sent += static_cast<std::size_t>(n);
  }
  std::size_t nl;
  while ((nl = in_.find('\n')) == std::string::npos) {
    char buf[512];
    const auto n = ::recv(fd_, buf, sizeof buf, 0);
    if (n < 0 && errno == EINTR) continue;
    if (n == 0) return fail("closed by fogbench-sim");
    if (n < 0)
      return fail(errno == EAGAIN || errno == EWOULDBLOCK
                      ? "no reply to advance within " + std::to_string(timeout_.count()) + " ms"
                      : std::string("recv: ") + std::strerror(errno));
    in_.append(buf, static_cast<std::size_t>(n));
    if (in_.size() > 65536) return fail("reply line too long");
  }
  const std::string line = in_.substr(0, nl);
  in_.erase(0, nl + 1);
  const auto reply = nlohmann::json::parse(line, nullptr, false);
  if (!reply.is_object()) return fail("reply is not JSON: " + line);
  if (reply.value("ok", false) != true || !reply.contains("time_s") || !reply["time_s"].is_number())
    return std::unexpected(control_.string() + ": advance refused: " + reply.value("error", line));
  return reply["time_s"].get<double>();
}

}  // namespace fogbench::daemon
