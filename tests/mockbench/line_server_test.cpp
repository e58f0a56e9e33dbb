// The mock bench's LineServer in-process, over real sockets but without a program: the control
// socket's form (a unix stream socket, LF-ended JSON lines, a too long line told and closed),
// the ASCII peers' form (TCP, a CR or an LF ends a line), and replies that a slow client takes
// later instead of being closed for them.
#include <catch2/catch.hpp>

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>

#include "line_server.hpp"
#include "poll_set.hpp"

using namespace fogbench::mock;

namespace {

// A short private directory (a unix socket path must stay under 108 bytes).
struct LineServerTempDir {
  std::filesystem::path path;
  LineServerTempDir() {
    char name[] = "/tmp/fb-lines.XXXXXX";
    REQUIRE(::mkdtemp(name) != nullptr);
    path = name;
  }
  ~LineServerTempDir() { std::filesystem::remove_all(path); }
};

int connect_unix_client(const std::string& path) {
  const int fd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
  REQUIRE(fd >= 0);
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  std::memcpy(addr.sun_path, path.c_str(), path.size() + 1);
  REQUIRE(::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0);
  ::fcntl(fd, F_SETFL, O_NONBLOCK);
  return fd;
}

int connect_tcp_client(int port) {
  const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  REQUIRE(fd >= 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<std::uint16_t>(port));
  ::inet_pton(AF_INET, "127.0.0.1", &addr.sin_addr);
  REQUIRE(::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0);
  ::fcntl(fd, F_SETFL, O_NONBLOCK);
  return fd;
}

void send_all(int fd, const std::string& bytes) {
  REQUIRE(::send(fd, bytes.data(), bytes.size(), MSG_NOSIGNAL) == static_cast<ssize_t>(bytes.size()));
}

// What the client has received so far, and whether the server closed the connection.
struct Received {
  std::string text;
  bool closed = false;
};

// Runs the server's poll rounds and reads the client until `done` holds (or a bounded number of
// rounds: the check after it then fails with what arrived).
template <class Done>
Received pump(LineServer& server, int client, Done done, bool client_reads = true) {
  Received got;
  PollSet set;
  for (int round = 0; round < 500 && !done(got); ++round) {
    set.clear();
    (void)server.watch(set);
    REQUIRE(set.wait(20));
    set.dispatch([] { return true; });
    server.after_round(LineServer::Clock::now());
    while (client_reads && !got.closed) {
      char buf[65536];
      const auto n = ::recv(client, buf, sizeof buf, 0);
      if (n > 0) {
        got.text.append(buf, static_cast<std::size_t>(n));
      } else {
        got.closed = n == 0;
        break;
      }
    }
  }
  return got;
}

LineServer::Reply bracket(const std::string& line) { return {"<" + line + ">\n"}; }

}  // namespace

TEST_CASE("line server, unix socket: LF-ended lines answered in order, a too long line told and closed, the file removed") {
  LineServerTempDir dir;
  const std::string path = (dir.path / "control.sock").string();
  LineServer server("control socket", LineServer::UnixPath{path}, bracket,
                    LineServer::Options{.lf_only = true, .overflow_reply = "too long\n"});
  REQUIRE(server.open());
  CHECK(std::filesystem::is_socket(path));

  // A second listener on a live socket is refused and names the path.
  LineServer second("control socket", LineServer::UnixPath{path}, bracket, {});
  const auto refused = second.open();
  REQUIRE_FALSE(refused);
  CHECK(refused.error() == path + ": another process is listening there");

  const int client = connect_unix_client(path);
  // A line cut in two sends; the CR before the LF dropped, a CR inside a line kept (only an LF
  // ends a line here), empty lines passed over.
  send_all(client, "{\"a\":1}\r");
  send_all(client, "\n{\"b\":\r2}\n\n\r\n{\"c\":3}\n");
  const auto got = pump(server, client, [](const Received& r) { return r.text.find("<{\"c\":3}>\n") != std::string::npos; });
  CHECK(got.text == "<{\"a\":1}>\n<{\"b\":\r2}>\n<{\"c\":3}>\n");
  CHECK(server.open_clients() == 1);

  // More than max_line_bytes without an LF: the overflow reply, then the connection closed.
  send_all(client, std::string(LineServer::max_line_bytes + 1, 'x'));
  const auto over = pump(server, client, [](const Received& r) { return r.closed; });
  CHECK(over.text == "too long\n");
  CHECK(over.closed);
  CHECK(server.open_clients() == 0);
  ::close(client);

  server.close();
  CHECK_FALSE(std::filesystem::exists(path));
}

TEST_CASE("line server, TCP: a CR or an LF ends a line, and a too long line closes without a word") {
  LineServer server("chamber", "127.0.0.1", 0, bracket);
  REQUIRE(server.open());
  REQUIRE(server.port() > 0);
  const int client = connect_tcp_client(server.port());
  send_all(client, "TEMP?\rMON?\r\nMODE?\n");
  const auto got = pump(server, client, [](const Received& r) { return r.text.find("<MODE?>\n") != std::string::npos; });
  CHECK(got.text == "<TEMP?>\n<MON?>\n<MODE?>\n");

  send_all(client, std::string(LineServer::max_line_bytes + 1, 'x'));
  const auto over = pump(server, client, [](const Received& r) { return r.closed; });
  CHECK(over.text.empty());
  CHECK(over.closed);
  ::close(client);
}

TEST_CASE("line server: replies a client does not read at once wait for it, in order, up to max_unsent_bytes") {
  LineServerTempDir dir;
  const std::string path = (dir.path / "big.sock").string();
  // Each reply 64 KiB, its line's number first: ten of them are more than a unix socket's buffer
  // (about 200 KiB by default), less than max_unsent_bytes (1 MiB).
  auto big = [](const std::string& line) { return LineServer::Reply{line + std::string(65536 - line.size() - 1, '.') + "\n"}; };
  LineServer server("control socket", LineServer::UnixPath{path}, big, LineServer::Options{.lf_only = true, .overflow_reply = ""});
  REQUIRE(server.open());

  const int reader = connect_unix_client(path);
  std::string requests;
  for (int i = 0; i < 10; ++i) requests += std::to_string(i) + "\n";
  send_all(reader, requests);
  // The server's rounds first, nothing read: the replies stay queued, the client stays open.
  int rounds = 0;
  (void)pump(server, reader, [&](const Received&) { return ++rounds > 5; }, false);
  CHECK(server.open_clients() == 1);
  const auto got = pump(server, reader, [](const Received& r) { return r.text.size() >= 10 * 65536; });
  REQUIRE(got.text.size() == 10 * 65536);
  for (int i = 0; i < 10; ++i) {
    INFO("reply " << i);
    CHECK(got.text.substr(static_cast<std::size_t>(i) * 65536, 2) == std::to_string(i) + ".");
  }
  ::close(reader);

  // A client that never reads while more than max_unsent_bytes pile up is closed.
  const int sleeper = connect_unix_client(path);
  requests.clear();
  for (int i = 0; i < 30; ++i) requests += std::to_string(i) + "\n";
  send_all(sleeper, requests);
  (void)pump(server, sleeper, [&](const Received&) { return server.open_clients() == 0; }, false);
  CHECK(server.open_clients() == 0);
  ::close(sleeper);
}
