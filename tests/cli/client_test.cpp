// fogctl's client without a daemon: --connect's HOST:PORT and what it says when it is wrong, and the
// client against a fake daemon (another protocol version, a line that never ends).
#include <catch2/catch.hpp>

#include "client.hpp"
#include "client_commands.hpp"

using fogbench::cli::parse_connect;

TEST_CASE("fogctl --connect: HOST:PORT, IPv6 in brackets") {
  auto a = parse_connect("127.0.0.1:7300");
  REQUIRE(a.has_value());
  CHECK(a->tcp_host == "127.0.0.1");
  CHECK(a->tcp_port == 7300);
  auto b = parse_connect("[::1]:1");
  REQUIRE(b.has_value());
  CHECK(b->tcp_host == "::1");
  CHECK(b->tcp_port == 1);
  auto c = parse_connect("bench7.lab:65535");
  REQUIRE(c.has_value());
  CHECK(c->tcp_host == "bench7.lab");
  CHECK(c->tcp_port == 65535);
}

TEST_CASE("fogctl --connect: a bad endpoint is an error naming the option and what is wrong") {
  const std::pair<const char*, const char*> cases[] = {
      {"127.0.0.1", "no port"},
      {":7300", "no host"},
      {"[]:7300", "no host"},
      {"host:", "not a number"},
      {"host:http", "not a number"},
      {"host:-1", "not a number"},
      {"host:0", "1..65535"},
      {"host:65536", "1..65535"},
      {"host:123456", "not a number"},
  };
  for (const auto& [text, why] : cases) {
    INFO(text);
    auto r = parse_connect(text);
    REQUIRE_FALSE(r.has_value());
    CHECK_THAT(r.error(), Catch::Contains("--connect: ") && Catch::Contains(why) && Catch::Contains(text));
  }
}

// --- The client against a fake daemon on a real unix socket: what it accepts from the other end.
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <atomic>
#include <cstring>
#include <filesystem>
#include <string>
#include <thread>

#include "fogbench/protocol/protocol.hpp"

namespace {

// Listens on a fresh unix socket; serve(fn) accepts one connection on a thread and runs fn on its
// descriptor, which is closed after it.
class FakeDaemon {
 public:
  FakeDaemon() {
    path_ = (std::filesystem::temp_directory_path() /
             ("fogctl-fake-" + std::to_string(::getpid()) + "-" + std::to_string(counter()++) + ".sock"))
                .string();
    std::filesystem::remove(path_);
    fd_ = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
    REQUIRE(fd_ >= 0);
    sockaddr_un addr{};
    addr.sun_family = AF_UNIX;
    std::memcpy(addr.sun_path, path_.c_str(), path_.size() + 1);
    REQUIRE(::bind(fd_, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0);
    REQUIRE(::listen(fd_, 1) == 0);
  }
  ~FakeDaemon() {
    if (thread_.joinable()) thread_.join();
    ::close(fd_);
    std::filesystem::remove(path_);
  }
  template <class Fn>
  void serve(Fn fn) {
    thread_ = std::thread([this, fn] {
      const int c = ::accept(fd_, nullptr, nullptr);
      if (c < 0) return;
      fn(c);
      ::close(c);
    });
  }
  const std::string& path() const { return path_; }

  // Sends all of `text`; false once the peer is gone.
  static bool send_all(int fd, const std::string& text) {
    std::size_t sent = 0;
    while (sent < text.size()) {
      const ssize_t n = ::send(fd, text.data() + sent, text.size() - sent, MSG_NOSIGNAL);
      if (n <= 0) return false;
      sent += static_cast<std::size_t>(n);
    }
    return true;
  }

 private:
  static std::atomic<int>& counter() {
    static std::atomic<int> n{0};
    return n;
  }
  std::string path_;
  int fd_ = -1;
  std::thread thread_;
};

std::string hello_line(int protocol_version) {
  auto h = fogbench::protocol::to_json(fogbench::protocol::Hello{"9.9.9"});
  h["protocol"] = protocol_version;
  return h.dump() + "\n";
}

// Sends x's (no newline) until the client hangs up, or a hard stop at twice the limit.
void endless_line(int fd) {
  const std::string chunk(1 << 20, 'x');
  for (std::size_t sent = 0; sent < 2 * fogbench::protocol::kMaxMessageBytes; sent += chunk.size())
    if (!FakeDaemon::send_all(fd, chunk)) return;
}

}  // namespace

TEST_CASE("fogctl client: a daemon of another protocol version is refused at hello, naming both versions") {
  FakeDaemon d;
  d.serve([](int fd) { FakeDaemon::send_all(fd, hello_line(fogbench::protocol::kProtocolVersion + 1)); });
  auto c = fogbench::cli::Client::connect(d.path(), 5000);
  REQUIRE_FALSE(c.has_value());
  CHECK(c.error().code == fogbench::cli::ClientErrc::protocol);
  CHECK_THAT(c.error().message, Catch::Contains("speaks protocol " + std::to_string(fogbench::protocol::kProtocolVersion + 1)) &&
                                    Catch::Contains("this client speaks protocol " + std::to_string(fogbench::protocol::kProtocolVersion)) &&
                                    Catch::Contains("9.9.9"));
}

TEST_CASE("fogctl client: a hello without a protocol version is refused") {
  FakeDaemon d;
  d.serve([](int fd) { FakeDaemon::send_all(fd, "{\"type\":\"hello\",\"version\":\"0.0.1\"}\n"); });
  auto c = fogbench::cli::Client::connect(d.path(), 5000);
  REQUIRE_FALSE(c.has_value());
  CHECK(c.error().code == fogbench::cli::ClientErrc::protocol);
  CHECK_THAT(c.error().message, Catch::Contains("no protocol version"));
}

TEST_CASE("fogctl client: the daemon's hello of this version is taken") {
  FakeDaemon d;
  d.serve([](int fd) { FakeDaemon::send_all(fd, hello_line(fogbench::protocol::kProtocolVersion)); });
  auto c = fogbench::cli::Client::connect(d.path(), 5000);
  REQUIRE(c.has_value());
  CHECK(c->hello()["version"] == "9.9.9");
}

TEST_CASE("fogctl client: an endless line from the daemon is an error naming the limit, not unbounded memory") {
  FakeDaemon d;
  // A good hello, then a reply that never ends.
  d.serve([](int fd) {
    if (FakeDaemon::send_all(fd, hello_line(fogbench::protocol::kProtocolVersion))) endless_line(fd);
  });
  auto c = fogbench::cli::Client::connect(d.path(), 5000);
  REQUIRE(c.has_value());
  auto r = c->call("status", nlohmann::json::object(), 60000);
  REQUIRE_FALSE(r.has_value());
  CHECK(r.error().code == fogbench::cli::ClientErrc::protocol);
  CHECK_THAT(r.error().message, Catch::Contains(std::to_string(fogbench::protocol::kMaxMessageBytes) + " bytes") &&
                                    Catch::Contains("kMaxMessageBytes"));
}

TEST_CASE("fogctl client: an endless hello is refused the same way") {
  FakeDaemon d;
  d.serve(endless_line);
  auto c = fogbench::cli::Client::connect(d.path(), 60000);
  REQUIRE_FALSE(c.has_value());
  CHECK(c.error().code == fogbench::cli::ClientErrc::protocol);
  CHECK_THAT(c.error().message, Catch::Contains(std::to_string(fogbench::protocol::kMaxMessageBytes) + " bytes"));
}

TEST_CASE("fogctl client: an error reply carries its code as an enum, and an unknown one as received") {
  FakeDaemon d;
  // Answers two requests (ids 1 and 2) with a known and an unknown error code.
  d.serve([](int fd) {
    if (!FakeDaemon::send_all(fd, hello_line(fogbench::protocol::kProtocolVersion))) return;
    std::string got;
    char buf[4096];
    for (int answered = 0; answered < 2;) {
      const ssize_t n = ::recv(fd, buf, sizeof buf, 0);
      if (n <= 0) return;
      got.append(buf, static_cast<std::size_t>(n));
      for (auto nl = got.find('\n'); nl != std::string::npos; nl = got.find('\n')) {
        const auto req = nlohmann::json::parse(got.substr(0, nl));
        got.erase(0, nl + 1);
        const char* code = ++answered == 1 ? "busy" : "quantum_flux";
        nlohmann::json reply = {{"type", "reply"}, {"id", req["id"]}, {"error", {{"code", code}, {"message", "no"}}}};
        if (!FakeDaemon::send_all(fd, reply.dump() + "\n")) return;
      }
    }
  });
  auto c = fogbench::cli::Client::connect(d.path(), 5000);
  REQUIRE(c.has_value());
  auto busy = c->call("run.start", nlohmann::json::object(), 5000);
  REQUIRE_FALSE(busy.has_value());
  CHECK(busy.error().code == fogbench::cli::ClientErrc::reply);
  CHECK(busy.error().reply_code == fogbench::protocol::ErrorCode::busy);
  CHECK(busy.error().reply_code_text == "busy");
  auto odd = c->call("status", nlohmann::json::object(), 5000);
  REQUIRE_FALSE(odd.has_value());
  CHECK(odd.error().code == fogbench::cli::ClientErrc::reply);
  CHECK_FALSE(odd.error().reply_code.has_value());
  CHECK(odd.error().reply_code_text == "quantum_flux");
}

TEST_CASE("fogctl status: the plant's line says a stalled link, its run and how long without progress") {
  using fogbench::cli::commands::plant_status_text;
  const nlohmann::json stalled = {{"bench_id", "b7"},          {"outbox_depth", 2},     {"sent", 5},
                                  {"last_error", nullptr},     {"link", "stalled"},     {"stalled", true},
                                  {"sending_run_id", 12},      {"link_busy_s", 14.3},  {"link_quiet_s", 9.5}};
  CHECK(plant_status_text(stalled) ==
        "plant: bench 'b7', outbox 2 waiting, 5 sent; link STALLED sending run 12 for 14.3 s, no progress for 9.5 s");
  const nlohmann::json idle = {{"bench_id", "b7"}, {"outbox_depth", 0}, {"sent", 5}, {"last_error", "connect: refused"},
                               {"link", "idle"},   {"stalled", false},  {"sending_run_id", nullptr},
                               {"link_busy_s", 0}, {"link_quiet_s", 0}};
  CHECK(plant_status_text(idle) == "plant: bench 'b7', outbox 0 waiting, 5 sent; link idle; last error: connect: refused");
  // A daemon without the link's fields (older): the outbox alone.
  CHECK(plant_status_text({{"bench_id", "b7"}, {"outbox_depth", 1}, {"sent", 0}}) ==
        "plant: bench 'b7', outbox 1 waiting, 0 sent");
}
