// socket.max_clients counts the network's connections to fogbenchd together: the TCP socket's
// sessions, the WebSockets and the plain HTTP connections of the web side (docs/web.md, "Who may
// do what"). One past it gets 503 over HTTP, a refused handshake as a WebSocket and `busy` on
// TCP; the clients already connected are served as before, and the unix socket, which has its
// own limit (socket.unix_max_clients), is not touched by it.
#include <catch2/catch.hpp>

#include "../daemon/live_bench.hpp"
#include "web_client.hpp"

using namespace fogbench::daemon::test;
using namespace fogbench::daemon::test::live;
using namespace fogbench::web_test;
using nlohmann::json;

namespace {

// A keep-alive HTTP/1.1 connection: each get() one request and its response on it.
class KeepAlive {
 public:
  explicit KeepAlive(std::uint16_t port) : stream_(io_) {
    beast::error_code ec;
    stream_.socket().connect(tcp::endpoint(asio::ip::make_address("127.0.0.1"), port), ec);
    ok_ = !ec;
  }
  // The status of GET target (0: no answer, the connection closed or timed out).
  int get(const std::string& target) {
    if (!ok_) return 0;
    http::request<http::empty_body> req(http::verb::get, target, 11);
    req.set(http::field::host, "127.0.0.1");
    req.keep_alive(true);
    http::response_parser<http::string_body> parser;
    parser.body_limit(64u << 20);
    int status = 0;
    bool done = false;
    http::async_write(stream_, req, [&](beast::error_code e, std::size_t) {
      if (e) {
        done = true;
        return;
      }
      http::async_read(stream_, buf_, parser, [&](beast::error_code e2, std::size_t) {
        done = true;
        if (!e2) status = static_cast<int>(parser.get().result_int());
      });
    });
    io_.restart();
    const auto deadline = std::chrono::steady_clock::now() + 20s;
    while (!done && std::chrono::steady_clock::now() < deadline) io_.run_one_for(deadline - std::chrono::steady_clock::now());
    if (!done || status == 0) ok_ = false;
    return status;
  }
  void close() {
    beast::error_code ec;
    stream_.socket().shutdown(tcp::socket::shutdown_both, ec);
    stream_.socket().close(ec);
    ok_ = false;
  }

 private:
  asio::io_context io_;
  beast::tcp_stream stream_;
  beast::flat_buffer buf_;
  bool ok_ = false;
};

// Polls GET /metrics on new connections until it has `status` (the daemon sees a close a moment
// after the client made it).
bool eventually_status(std::uint16_t port, int status) {
  const auto deadline = std::chrono::steady_clock::now() + 20s;
  while (std::chrono::steady_clock::now() < deadline) {
    if (http_get(port, "/metrics").status == status) return true;
    std::this_thread::sleep_for(100ms);
  }
  return false;
}

}  // namespace

TEST_CASE("socket.max_clients counts HTTP and WebSocket connections with TCP's: one past it gets 503, the others go on") {
  require_sim();
  const auto tcp_port = free_port();
  LiveBench bench(20.0, {{"web", {{"listen", "127.0.0.1:0"}}},
                         {"socket", {{"max_clients", 3}, {"first_request_timeout_s", 3600}, {"tcp", {{"port", tcp_port}, {"token", "web-limits-token-0123456789"}}}}}});
  REQUIRE(bench.ready_daemon["web_port"].is_number_integer());
  const auto port = bench.ready_daemon["web_port"].get<std::uint16_t>();

  // Three clients: two keep-alive HTTP connections and one on TCP.
  KeepAlive a(port), b(port);
  REQUIRE(a.get("/metrics") == 200);
  REQUIRE(b.get("/") == 200);
  LineClient c(tcp_port);
  REQUIRE(c.ok());
  REQUIRE(code_of(c.call({{"cmd", "status"}})) == "ok");

  // The fourth: 503 over HTTP, its reason named; a WebSocket refused; busy on TCP.
  auto over = http_get(port, "/metrics");
  CHECK(over.status == 503);
  CHECK_THAT(over.body, Catch::Contains("socket.max_clients"));
  CHECK(over.closed);
  WsClient ws_over("127.0.0.1", port, "/ws");
  CHECK_FALSE(ws_over.ok());
  {
    LineClient d(tcp_port);
    REQUIRE(d.ok());
    auto line = d.line(10s);
    REQUIRE(line);
    const json busy = json::parse(*line, nullptr, false);
    CHECK(code_of(busy) == "busy");
  }
  // The unix socket has its own places: the operator is served.
  {
    LineClient u(bench.socket());
    REQUIRE(u.ok());
    CHECK(code_of(u.call({{"cmd", "status"}})) == "ok");
  }

  // The clients already connected are served as before.
  CHECK(a.get("/metrics") == 200);
  CHECK(b.get("/panel.js") == 200);
  CHECK(code_of(c.call({{"cmd", "status"}})) == "ok");

  // One HTTP connection closed makes room: for a WebSocket, which then counts in its turn.
  a.close();
  CHECK(eventually_status(port, 200));
  WsClient ws("127.0.0.1", port, "/ws");
  REQUIRE(ws.ok());
  CHECK(json::parse(ws.read().value_or("null"), nullptr, false)["type"] == "hello");
  CHECK(http_get(port, "/metrics").status == 503);
  CHECK(ws.call({{"cmd", "status"}})["result"].is_object());
  CHECK(b.get("/metrics") == 200);
}
