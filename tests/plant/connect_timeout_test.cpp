// A plant that accepts TCP but never answers (a frozen server, a firewall that lets the handshake
// through) must not hold a connection attempt for the kernel's two minutes (issue 27): the
// bound given to Connection::open ends it, and a connect_timeout written in the conninfo wins
// over that bound. No PostgreSQL is needed: a socket that listens and never accepts is the peer.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <catch2/catch.hpp>
#include <string>

#include "fogbench/plant/plant.hpp"

namespace {

// Listens on 127.0.0.1 (a free port) and never accepts: the kernel completes the handshake,
// libpq sends its start-up packet and waits for an answer that never comes.
class SilentListener {
 public:
  SilentListener() {
    fd_ = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    REQUIRE(fd_ >= 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    REQUIRE(::bind(fd_, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0);
    REQUIRE(::listen(fd_, 8) == 0);
    socklen_t n = sizeof a;
    REQUIRE(::getsockname(fd_, reinterpret_cast<sockaddr*>(&a), &n) == 0);
    port_ = ntohs(a.sin_port);
  }
  ~SilentListener() { ::close(fd_); }
  SilentListener(const SilentListener&) = delete;
  SilentListener& operator=(const SilentListener&) = delete;
  int port() const { return port_; }

 private:
  int fd_ = -1;
  int port_ = 0;
};

}  // namespace

TEST_CASE("plant connect: a server that never answers is given up after the bound, naming the timeout") {
  SilentListener peer;
  const std::string conninfo =
      "host=127.0.0.1 port=" + std::to_string(peer.port()) + " dbname=plant user=fogbench sslmode=disable";
  // libpq's smallest connect_timeout is 2 s.
  auto c = fogbench::plant::Connection::open(conninfo, false, 2);
  REQUIRE_FALSE(c);
  CHECK(c.error().code == fogbench::plant::PlantErrc::connect_failed);
  CHECK_THAT(c.error().message, Catch::StartsWith("connect to the plant store: ") && Catch::Contains("timeout"));
}

TEST_CASE("plant connect: a connect_timeout in the conninfo or URI wins over the bound") {
  SilentListener peer;
  const std::string port = std::to_string(peer.port());
  // With the bound of an hour applied instead, these would wait until the test's own limit.
  for (const std::string& conninfo :
       {"host=127.0.0.1 port=" + port + " dbname=plant user=fogbench sslmode=disable connect_timeout=2",
        "postgresql://fogbench@127.0.0.1:" + port + "/plant?sslmode=disable&connect_timeout=2"}) {
    INFO(conninfo);
    auto c = fogbench::plant::Connection::open(conninfo, false, 3600);
    REQUIRE_FALSE(c);
    CHECK(c.error().code == fogbench::plant::PlantErrc::connect_failed);
    CHECK_THAT(c.error().message, Catch::Contains("timeout"));
  }
}
