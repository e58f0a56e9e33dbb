// fogctl's client without a daemon: --connect's HOST:PORT and what it says when it is wrong.
#include <catch2/catch.hpp>

#include "client.hpp"

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
