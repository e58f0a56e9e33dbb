// sd_notify and the journal's stream format, written out (systemd.hpp): the protocol is a few
// lines over an AF_UNIX datagram socket, documented in sd_notify(3) as stable; libsystemd would
// add a run-time dependency for that alone.
#include "fogbench/daemon/systemd.hpp"

#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <cstddef>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <mutex>

#include <spdlog/sinks/base_sink.h>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

namespace fogbench::daemon::systemd {

bool notify_to(const std::string& path, std::string_view state) {
  if (path.empty() || path.size() >= sizeof(sockaddr_un::sun_path)) return false;
  if (path[0] != '/' && path[0] != '@') return false;
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  std::memcpy(addr.sun_path, path.data(), path.size());
  if (path[0] == '@') addr.sun_path[0] = '\0';  // the abstract namespace
  const auto len = static_cast<socklen_t>(offsetof(sockaddr_un, sun_path) + path.size());
  const int fd = ::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
  if (fd < 0) return false;
  const ssize_t n = ::sendto(fd, state.data(), state.size(), MSG_NOSIGNAL, reinterpret_cast<const sockaddr*>(&addr), len);
  ::close(fd);
  return n == static_cast<ssize_t>(state.size());
}

bool notify(std::string_view state) {
  const char* p = std::getenv("NOTIFY_SOCKET");
  return p && *p && notify_to(p, state);
}

std::optional<std::chrono::microseconds> watchdog_interval() {
  const char* usec = std::getenv("WATCHDOG_USEC");
  if (!usec || !*usec) return std::nullopt;
  if (const char* pid = std::getenv("WATCHDOG_PID"); pid && *pid && std::strtoll(pid, nullptr, 10) != ::getpid())
    return std::nullopt;
  char* end = nullptr;
  const long long v = std::strtoll(usec, &end, 10);
  if (end == usec || *end != '\0' || v <= 0) return std::nullopt;
  return std::chrono::microseconds(v);
}

bool stderr_is_journal() {
  const char* js = std::getenv("JOURNAL_STREAM");
  if (!js || !*js) return false;
  struct stat st {};
  if (::fstat(STDERR_FILENO, &st) != 0) return false;
  unsigned long long dev = 0, ino = 0;
  if (std::sscanf(js, "%llu:%llu", &dev, &ino) != 2) return false;
  return dev == static_cast<unsigned long long>(st.st_dev) && ino == static_cast<unsigned long long>(st.st_ino);
}

namespace {

int syslog_priority(spdlog::level::level_enum l) {
  switch (l) {
    case spdlog::level::trace:
    case spdlog::level::debug: return 7;
    case spdlog::level::info: return 6;
    case spdlog::level::warn: return 4;
    case spdlog::level::err: return 3;
    case spdlog::level::critical: return 2;
    default: return 6;
  }
}

// One journal entry per line of the message, each "<N>text"; trailing newlines dropped (they
// were the blank lines after events).
class JournalSink final : public spdlog::sinks::base_sink<std::mutex> {
 protected:
  void sink_it_(const spdlog::details::log_msg& msg) override {
    std::string_view text(msg.payload.data(), msg.payload.size());
    while (!text.empty() && (text.back() == '\n' || text.back() == '\r')) text.remove_suffix(1);
    const std::string prefix = "<" + std::to_string(syslog_priority(msg.level)) + ">";
    std::string out;
    std::size_t b = 0;
    for (;;) {
      const std::size_t e = text.find('\n', b);
      const std::string_view line = text.substr(b, e == std::string_view::npos ? std::string_view::npos : e - b);
      out += prefix;
      out += line;
      out += '\n';
      if (e == std::string_view::npos) break;
      b = e + 1;
    }
    std::fwrite(out.data(), 1, out.size(), stderr);
  }
  void flush_() override { std::fflush(stderr); }
};

}  // namespace

std::shared_ptr<spdlog::logger> stderr_logger(const std::string& name, bool journal) {
  if (!journal) return spdlog::stderr_color_mt(name);
  auto logger = std::make_shared<spdlog::logger>(name, std::make_shared<JournalSink>());
  spdlog::register_logger(logger);
  return logger;
}

}  // namespace fogbench::daemon::systemd
