// The connection limits of fogbenchd (daemon/src/admission.hpp, docs/reliability.md "Connection
// limits") without a daemon: each listener's own count, the unix socket's share that network
// clients never take, the per-address count over TCP and the web, places given back, the refusal
// log's one line per interval with a count; and the configuration keys with their errors.
#include "fixture.hpp"

#include "../../daemon/src/admission.hpp"

using namespace fogbench::daemon;
using namespace fogbench::daemon::net;
using fogbench::daemon::test::golden_config_json;
using fogbench::daemon::test::golden_dir;

namespace {

AdmissionLimits limits(std::size_t unix_max, std::size_t network_max, std::size_t per_address_max) {
  AdmissionLimits l;
  l.unix_max = unix_max;
  l.network_max = network_max;
  l.per_address_max = per_address_max;
  return l;
}

std::string refusal(nlohmann::json patch) {
  auto j = golden_config_json();
  j.merge_patch(patch);
  auto c = parse_daemon_config(j, golden_dir());
  REQUIRE_FALSE(c.has_value());
  return c.error();
}

}  // namespace

TEST_CASE("admission: network clients at socket.max_clients leave the unix socket's share free") {
  Admission a(limits(2, 4, 100));
  std::vector<Admission::Ticket> held;
  // TCP and the web fill their shared limit from several addresses.
  for (int i = 0; i < 4; ++i) {
    CHECK_FALSE(a.network_full());
    auto t = a.admit(i % 2 ? Listener::tcp : Listener::web, "10.0.0." + std::to_string(i));
    REQUIRE(t.has_value());
    held.push_back(*t);
  }
  CHECK(a.network_full());  // the acceptors pause after a refusal now
  auto over = a.admit(Listener::tcp, "10.0.0.9");
  REQUIRE_FALSE(over.has_value());
  CHECK_THAT(over.error(), Catch::Contains("socket.max_clients"));
  CHECK_THAT(over.error(), Catch::Contains("4 connected"));
  CHECK_FALSE(a.admit(Listener::web, "10.0.0.9").has_value());
  // Before issue 27 the unix socket shared that limit: now it has its own two places.
  auto u1 = a.admit(Listener::unix_socket, "");
  auto u2 = a.admit(Listener::unix_socket, "");
  REQUIRE(u1.has_value());
  REQUIRE(u2.has_value());
  auto u3 = a.admit(Listener::unix_socket, "");
  REQUIRE_FALSE(u3.has_value());
  CHECK_THAT(u3.error(), Catch::Contains("socket.unix_max_clients"));
  CHECK(a.unix_open() == 2);
  CHECK(a.tcp_open() == 2);
  CHECK(a.web_open() == 2);
  // A unix client gone frees a unix place, not a network one.
  u1->reset();
  CHECK(a.unix_open() == 1);
  CHECK(a.admit(Listener::unix_socket, "").has_value());
  CHECK_FALSE(a.admit(Listener::tcp, "10.0.0.9").has_value());
  // A network client gone frees a network place.
  held.pop_back();
  CHECK_FALSE(a.network_full());
  CHECK(a.admit(Listener::tcp, "10.0.0.9").has_value());
}

TEST_CASE("admission: one address over socket.max_clients_per_address is refused while another is not") {
  Admission a(limits(8, 100, 3));
  std::vector<Admission::Ticket> held;
  // TCP and web count together for an address.
  for (Listener l : {Listener::tcp, Listener::web, Listener::tcp}) {
    auto t = a.admit(l, "127.0.0.1");
    REQUIRE(t.has_value());
    held.push_back(*t);
  }
  CHECK(a.from("127.0.0.1") == 3);
  auto over = a.admit(Listener::web, "127.0.0.1");
  REQUIRE_FALSE(over.has_value());
  CHECK_THAT(over.error(), Catch::Contains("127.0.0.1"));
  CHECK_THAT(over.error(), Catch::Contains("socket.max_clients_per_address"));
  CHECK_FALSE(a.network_full());  // one address's limit: the acceptors go on (the others come in)
  auto other = a.admit(Listener::tcp, "127.0.0.2");
  REQUIRE(other.has_value());
  CHECK(a.from("127.0.0.2") == 1);
  // A refusal takes no place.
  CHECK(a.from("127.0.0.1") == 3);
  CHECK(a.tcp_open() == 3);
  // Every copy of a ticket must go before its place is free (a WebSocket keeps its HTTP one's).
  Admission::Ticket copy = held[0];
  held.erase(held.begin());
  CHECK(a.from("127.0.0.1") == 3);
  copy.reset();
  CHECK(a.from("127.0.0.1") == 2);
  CHECK(a.admit(Listener::tcp, "127.0.0.1").has_value());
}

TEST_CASE("admission: a ticket may outlive the Admission that gave it (connections ending on the way out)") {
  Admission::Ticket t;
  {
    Admission a(limits(1, 1, 1));
    t = *a.admit(Listener::tcp, "10.1.1.1");
  }
  t.reset();  // no use of freed memory (run under ASan in CI)
  SUCCEED();
}

TEST_CASE("refusal log: the first refusal in full, the rest of the interval as one line with the count") {
  using C = RefusalLog::Clock;
  RefusalLog log(std::chrono::seconds(60));
  const C::time_point t0{};
  auto first = log.refused(Listener::tcp, "10.0.0.1:5000", "too many network clients (...)", t0);
  REQUIRE(first.has_value());
  CHECK_THAT(*first, Catch::Contains("10.0.0.1:5000"));
  CHECK_THAT(*first, Catch::Contains("too many network clients"));
  CHECK_THAT(*first, Catch::Contains("every 60 s"));
  REQUIRE(log.flush_due().has_value());
  CHECK(*log.flush_due() == t0 + std::chrono::seconds(60));
  // 20,000 more within the interval: not one line.
  int lines = 0;
  for (int i = 0; i < 20000; ++i) {
    const Listener l = i % 4 == 0 ? Listener::web : (i % 4 == 1 ? Listener::unix_socket : Listener::tcp);
    if (log.refused(l, "x", i == 19999 ? "the last reason" : "why", t0 + std::chrono::milliseconds(i)).has_value())
      ++lines;
  }
  CHECK(lines == 0);
  auto summary = log.flush(t0 + std::chrono::seconds(60));
  REQUIRE(summary.has_value());
  CHECK_THAT(*summary, Catch::StartsWith("20000 more connections refused in the last 60 s"));
  CHECK_THAT(*summary, Catch::Contains("unix 5000, tcp 10000, web 5000"));
  CHECK_THAT(*summary, Catch::Contains("the last: the last reason"));
  // A steady stream: the next interval's refusals are counted too, one line at its end.
  CHECK_FALSE(log.refused(Listener::tcp, "x", "why", t0 + std::chrono::seconds(61)).has_value());
  auto second = log.flush(t0 + std::chrono::seconds(120));
  REQUIRE(second.has_value());
  CHECK_THAT(*second, Catch::StartsWith("1 more connections refused"));
  // A quiet interval ends the spell: nothing to say, and the next refusal is logged in full.
  CHECK_FALSE(log.flush(t0 + std::chrono::seconds(180)).has_value());
  CHECK_FALSE(log.flush_due().has_value());
  CHECK(log.refused(Listener::web, "y", "why", t0 + std::chrono::seconds(200)).has_value());
}

TEST_CASE("config: the connection limits, their defaults and errors naming the field") {
  auto c = parse_daemon_config(golden_config_json(), golden_dir());
  REQUIRE(c.has_value());
  CHECK(c->socket.max_clients == 256);
  CHECK(c->socket.unix_max_clients == 64);
  CHECK(c->socket.max_clients_per_address == 32);
  CHECK(c->socket.max_analyses_per_address == 4);
  REQUIRE(c->socket.first_request_timeout_s.has_value());
  CHECK(*c->socket.first_request_timeout_s == 10.0);
  CHECK(c->socket.refusal_log_interval_s == 60.0);

  auto j = golden_config_json();
  j.merge_patch({{"socket", {{"max_clients", 5}, {"unix_max_clients", 2}, {"max_clients_per_address", 3},
                             {"max_analyses_per_address", 1}, {"refusal_log_interval_s", 2.5}}}});
  j["socket"]["first_request_timeout_s"] = nullptr;  // after the merge: a patch's null deletes
  auto d = parse_daemon_config(j, golden_dir());
  REQUIRE(d.has_value());
  CHECK(d->socket.max_clients == 5);
  CHECK(d->socket.unix_max_clients == 2);
  CHECK(d->socket.max_clients_per_address == 3);
  CHECK(d->socket.max_analyses_per_address == 1);
  CHECK_FALSE(d->socket.first_request_timeout_s.has_value());
  CHECK(d->socket.refusal_log_interval_s == 2.5);

  CHECK(refusal({{"socket", {{"unix_max_clients", 0}}}}) == "socket.unix_max_clients: expected an integer 1..100000");
  CHECK(refusal({{"socket", {{"unix_max_clients", "many"}}}}) == "socket.unix_max_clients: expected an integer 1..100000");
  CHECK(refusal({{"socket", {{"max_clients_per_address", 100001}}}}) ==
        "socket.max_clients_per_address: expected an integer 1..100000");
  CHECK(refusal({{"socket", {{"max_analyses_per_address", 0}}}}) ==
        "socket.max_analyses_per_address: expected an integer 1..100000");
  CHECK(refusal({{"socket", {{"max_clients", 2.5}}}}) == "socket.max_clients: expected an integer 1..100000");
  CHECK_THAT(refusal({{"socket", {{"first_request_timeout_s", 0}}}}), Catch::StartsWith("socket.first_request_timeout_s: "));
  CHECK_THAT(refusal({{"socket", {{"first_request_timeout_s", "soon"}}}}),
             Catch::StartsWith("socket.first_request_timeout_s: expected a number"));
  CHECK_THAT(refusal({{"socket", {{"refusal_log_interval_s", 0}}}}), Catch::StartsWith("socket.refusal_log_interval_s: "));
  CHECK_THAT(refusal({{"socket", {{"max_client", 5}}}}), Catch::StartsWith("socket.max_client: unknown field"));
}
