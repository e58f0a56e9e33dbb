// Who may reach the web panel's data by name (config.hpp's web_host_allowed and
// web_origin_allowed): an address, localhost or a name of web.hosts in Host; an Origin only when
// it is that Host. DNS rebinding (a page whose own name now points at the bench) sends Host and
// Origin that agree with each other, on a name the panel does not have: refused.
#include <catch2/catch.hpp>

#include "fogbench/daemon/config.hpp"

using namespace fogbench;
using nlohmann::json;

TEST_CASE("web: Host must name the panel: an IP address, localhost or one of web.hosts") {
  auto w = daemon::parse_web_config(json{{"listen", "127.0.0.1:8080"}});
  REQUIRE(w.has_value());
  for (const char* ok : {"127.0.0.1", "127.0.0.1:8080", "[::1]:8080", "[::1]", "localhost", "localhost:8080",
                         "LOCALHOST:8080", "192.0.2.7:8080", ""})
    CHECK(daemon::web_host_allowed(*w, ok));
  // The rebinding attack's names, and malformed ones.
  for (const char* refused : {"evil.example", "evil.example:8080", "bench7.example:8080", "localhost.evil.example",
                              "127.0.0.1.evil.example:8080", "[::1", "a:b:c", "[::1]x"})
    CHECK_FALSE(daemon::web_host_allowed(*w, refused));

  auto named = daemon::parse_web_config(json{{"listen", "0.0.0.0:8080"}, {"allow_remote", true}, {"hosts", {"Bench7.Example"}}});
  REQUIRE(named.has_value());
  CHECK(named->hosts == std::vector<std::string>{"bench7.example"});
  CHECK(daemon::web_host_allowed(*named, "bench7.example:8080"));
  CHECK(daemon::web_host_allowed(*named, "BENCH7.example"));
  CHECK_FALSE(daemon::web_host_allowed(*named, "evil.example:8080"));
}

TEST_CASE("web: an Origin must be the request's own Host, on a name of the panel") {
  auto w = daemon::parse_web_config(json{{"listen", "127.0.0.1:8080"}, {"hosts", {"bench7.example"}}});
  REQUIRE(w.has_value());
  CHECK(daemon::web_origin_allowed(*w, "", "127.0.0.1:8080"));  // no Origin: not a browser
  CHECK(daemon::web_origin_allowed(*w, "http://127.0.0.1:8080", "127.0.0.1:8080"));
  CHECK(daemon::web_origin_allowed(*w, "http://bench7.example:8080", "bench7.example:8080"));
  // Cross-site: another origin than the Host.
  CHECK_FALSE(daemon::web_origin_allowed(*w, "http://evil.example", "127.0.0.1:8080"));
  CHECK_FALSE(daemon::web_origin_allowed(*w, "http://127.0.0.1:9999", "127.0.0.1:8080"));
  CHECK_FALSE(daemon::web_origin_allowed(*w, "null", "127.0.0.1:8080"));
  // DNS rebinding: Origin and Host agree, on a name the panel does not have.
  CHECK_FALSE(daemon::web_origin_allowed(*w, "http://evil.example:8080", "evil.example:8080"));
}

TEST_CASE("web: web.hosts takes host names only, naming the field") {
  auto err = [](const json& hosts) {
    auto w = daemon::parse_web_config(json{{"listen", "127.0.0.1:8080"}, {"hosts", hosts}});
    REQUIRE_FALSE(w.has_value());
    return w.error();
  };
  CHECK_THAT(err("bench7"), Catch::StartsWith("web.hosts: expected an array of host names"));
  CHECK_THAT(err(json::array({7})), Catch::StartsWith("web.hosts: expected an array of host names"));
  CHECK_THAT(err(json::array({"bench7:8080"})), Catch::StartsWith("web.hosts: \"bench7:8080\" is not a host name"));
  CHECK_THAT(err(json::array({"http://bench7"})), Catch::StartsWith("web.hosts: \"http://bench7\" is not a host name"));
  CHECK_THAT(err(json::array({""})), Catch::StartsWith("web.hosts: \"\" is not a host name"));
}
