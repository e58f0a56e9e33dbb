// fogbenchd's web side against a live daemon on the mock bench, without a browser: the embedded
// files, /metrics parsed by the exposition grammar, POST /api and the WebSocket with and without
// the control token, and bad input on the HTTP side (oversize headers and bodies, unknown paths,
// garbage requests, WebSocket garbage): each gets a clear error and the daemon goes on serving.
#include <catch2/catch.hpp>

#include "../daemon/live_bench.hpp"
#include "fogbench/daemon/handler.hpp"
#include "exposition.hpp"
#include "web_client.hpp"

using namespace fogbench::daemon::test;
using namespace fogbench::daemon::test::live;
using namespace fogbench::web_test;
using nlohmann::json;

namespace {
const std::string kToken = "web-test-token-0123456789";

std::string slurp(const std::filesystem::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::stringstream s;
  s << f.rdbuf();
  return s.str();
}

json web_patch(std::uint16_t tcp_port) {
  return {{"web", {{"listen", "127.0.0.1:0"}}}, {"socket", {{"tcp", {{"port", tcp_port}, {"token", kToken}}}}}};
}

std::uint16_t web_port(const LiveBench& b) {
  REQUIRE(b.ready_daemon.contains("web_port"));
  REQUIRE(b.ready_daemon["web_port"].is_number_integer());
  return b.ready_daemon["web_port"].get<std::uint16_t>();
}

// The daemon still answers on its command socket and on the web side.
void still_serving(LiveBench& b, std::uint16_t port) {
  LineClient c(b.socket());
  REQUIRE(c.ok());
  CHECK(code_of(c.call({{"cmd", "status"}})) == "ok");
  CHECK(http_get(port, "/metrics").status == 200);
}
}  // namespace

TEST_CASE("the panel's files, metrics and the protocol over HTTP and WebSocket, live") {
  require_sim();
  LiveBench bench(20.0, web_patch(free_port()), true);
  const auto port = web_port(bench);

  // The panel and its files, embedded: uPlot byte for byte the report's vendored copy.
  auto index = http_get(port, "/");
  REQUIRE(index.status == 200);
  CHECK(index.head.find("text/html") != std::string::npos);
  CHECK(index.body.find("/panel.js") != std::string::npos);
  auto uplot = http_get(port, "/uPlot.iife.min.js");
  REQUIRE(uplot.status == 200);
  CHECK(uplot.body == slurp(std::filesystem::path(FOGBENCH_SOURCE_DIR) / "cli/report/vendor/uPlot.iife.min.js"));
  CHECK(http_get(port, "/panel.js").body == slurp(std::filesystem::path(FOGBENCH_SOURCE_DIR) / "daemon/web/panel.js"));

  // The WebSocket: hello first, then the protocol; subscribed, it gets the samples of a run.
  WsClient ws("127.0.0.1", port, "/ws");
  REQUIRE(ws.ok());
  auto hello = json::parse(ws.read().value_or("null"), nullptr, false);
  CHECK(hello["type"] == "hello");
  CHECK(ws.call({{"cmd", "subscribe"}})["result"]["subscribed"] == true);
  LineClient c(bench.socket());
  REQUIRE(c.ok());
  const auto run = bench.start_run(c, "short", {"SIM-0001", "SIM-0002"});
  json sample;
  for (int i = 0; i < 200 && !sample.is_object(); ++i) {
    auto m = ws.read(60s);
    REQUIRE(m);
    auto j = json::parse(*m, nullptr, false);
    if (j.is_object() && j["type"] == "sample") sample = j;
  }
  REQUIRE(sample.is_object());
  CHECK(sample["run_id"] == run);
  for (const char* k : {"gyro_dph", "t1_c", "t2_c", "setpoint_c", "chamber_c", "serial"}) CHECK(sample.contains(k));

  // Control without the token: refused, over the WebSocket and over POST /api (403); the run goes on.
  auto refused = ws.call({{"cmd", "run.abort"}});
  CHECK(code_of(refused) == "forbidden");
  auto api = http_post(port, "/api", json{{"id", 1}, {"cmd", "run.abort"}}.dump());
  CHECK(api.status == 403);
  CHECK(code_of(json::parse(api.body, nullptr, false)) == "forbidden");
  auto wrong = http_post(port, "/api", json{{"id", 2}, {"cmd", "run.abort"}, {"token", "wrong-token-0123456789"}}.dump());
  CHECK(wrong.status == 403);
  CHECK(code_of(json::parse(wrong.body, nullptr, false)) == "forbidden");
  auto st = c.call({{"cmd", "status"}});
  REQUIRE(st["result"]["run"].is_object());
  CHECK(st["result"]["run"]["id"] == run);

  // Metrics while the run is active, parsed by the exposition grammar.
  auto m = http_get(port, "/metrics");
  REQUIRE(m.status == 200);
  CHECK(m.head.find("text/plain; version=0.0.4") != std::string::npos);
  const auto e = parse_exposition(m.body);
  INFO(m.body);
  for (const auto& err : e.errors) FAIL_CHECK(err);
  REQUIRE(e.find("fogbench_run_active").size() == 1u);
  CHECK(e.find("fogbench_run_active")[0].value == 1.0);
  REQUIRE(e.find("fogbench_run_id").size() == 1u);
  CHECK(e.find("fogbench_run_id")[0].value == static_cast<double>(run));
  CHECK(e.find("fogbench_unit_rate_degrees_per_hour", {{"serial", "SIM-0002"}}).size() == 1u);
  CHECK(e.find("fogbench_unit_frames_lost_total", {{"serial", "SIM-0001"}}).size() == 1u);
  REQUIRE(e.find("fogbench_clients", {{"transport", "web"}}).size() == 1u);
  // The WebSocket and this scrape's own HTTP connection.
  CHECK(e.find("fogbench_clients", {{"transport", "web"}})[0].value == 2.0);
  CHECK(e.find("fogbench_clients", {{"transport", "socket"}})[0].value >= 1.0);
  REQUIRE(e.find("fogbench_store_size_bytes").size() == 1u);
  CHECK(e.find("fogbench_store_size_bytes")[0].value > 4096.0);
  CHECK(e.find("fogbench_ticks_total")[0].value >= 1.0);

  // With the token: the same command is taken (over the web, by the same handler).
  auto aborted = ws.call({{"cmd", "run.abort"}, {"reason", "web test"}, {"token", kToken}});
  INFO(aborted.dump());
  CHECK(code_of(aborted) == "ok");
  auto got = bench.wait_state(c, run, {"aborted"}, 60s);
  CHECK(got["result"]["run"]["reason"] == "aborted by operator: web test");
}

TEST_CASE("every control command of the table is refused on the read-only TCP port, POST /api and the WebSocket, live") {
  require_sim();
  const auto tcp_port = free_port();
  LiveBench bench(20.0, web_patch(tcp_port), true);
  const auto port = web_port(bench);
  LineClient tcp(tcp_port);
  REQUIRE(tcp.ok());
  WsClient ws("127.0.0.1", port, "/ws");
  REQUIRE(ws.ok());
  std::size_t control = 0;
  for (const auto& c : fogbench::daemon::commands()) {
    const std::string name(c.name);
    INFO(name);
    if (c.access == fogbench::daemon::Access::read) {
      // Served (whatever it answers without arguments), not refused.
      CHECK(code_of(tcp.call({{"cmd", name}})) != "forbidden");
      continue;
    }
    ++control;
    const json by_tcp = tcp.call({{"cmd", name}});
    CHECK(code_of(by_tcp) == "forbidden");
    CHECK(by_tcp["error"]["message"] == name + ": needs a valid token on this connection");
    CHECK(code_of(tcp.call({{"cmd", name}, {"token", "wrong-token-0123456789"}})) == "forbidden");
    const auto api = http_post(port, "/api", json{{"id", 1}, {"cmd", name}}.dump());
    CHECK(api.status == 403);
    CHECK(code_of(json::parse(api.body, nullptr, false)) == "forbidden");
    CHECK(code_of(ws.call({{"cmd", name}})) == "forbidden");
  }
  CHECK(control >= 11u);
  // Nothing was started or queued.
  LineClient c(bench.socket());
  REQUIRE(c.ok());
  const json runs = c.call({{"cmd", "run.list"}});
  REQUIRE(runs.contains("result"));
  CHECK(runs["result"]["runs"].empty());
  const json queue = c.call({{"cmd", "queue.list"}});
  INFO(queue.dump());
  CHECK(code_of(queue) != "forbidden");
  still_serving(bench, port);
}

TEST_CASE("bad input on the HTTP side gets a clear error and the daemon goes on") {
  require_sim();
  LiveBench bench(20.0, web_patch(free_port()), true);
  const auto port = web_port(bench);

  auto nf = http_get(port, "/nope");
  CHECK(nf.status == 404);
  CHECK(nf.body.find("no such path: /nope") != std::string::npos);

  auto put = http_raw(port, "PUT / HTTP/1.1\r\nHost: x\r\nContent-Length: 0\r\nConnection: close\r\n\r\n");
  CHECK(put.status == 405);
  CHECK(put.head.find("Allow: GET, HEAD") != std::string::npos);
  CHECK(http_get(port, "/api").status == 405);

  // Headers over 8 KiB: 431 and the connection closed.
  auto big = http_raw(port, "GET / HTTP/1.1\r\nHost: x\r\nX-Big: " + std::string(20000, 'a') + "\r\n\r\n");
  CHECK(big.status == 431);
  CHECK(big.body.find("request headers over 8192 bytes") != std::string::npos);
  CHECK(big.closed);
  // A body over 64 KiB: 413 before it is read.
  auto body = http_raw(port, "POST /api HTTP/1.1\r\nHost: x\r\nContent-Length: 1000000\r\n\r\n" + std::string(1000, '{'));
  CHECK(body.status == 413);
  CHECK(body.body.find("request body over 65536 bytes") != std::string::npos);
  // Not HTTP at all.
  auto garbage = http_raw(port, "HELLO THERE\r\n\r\n");
  CHECK(garbage.status == 400);
  CHECK(garbage.body.find("bad HTTP request") != std::string::npos);
  // Binary junk.
  std::string junk;
  for (int i = 0; i < 4096; ++i) junk += static_cast<char>((i * 7919) & 0xff);
  auto j2 = http_raw(port, junk, 10s);
  CHECK((j2.status == 400 || j2.status == 0));
  // Not JSON to /api: the protocol's bad_json, as HTTP 400.
  auto bad = http_post(port, "/api", "{oops");
  CHECK(bad.status == 400);
  CHECK(code_of(json::parse(bad.body, nullptr, false)) == "bad_json");
  // /ws without the upgrade.
  CHECK(http_get(port, "/ws").status == 426);
  // A WebSocket opened by a page of another site (its Origin) is refused; from the panel's own
  // origin it is accepted (101).
  auto upgrade = [&](const std::string& origin) {
    return http_raw(port, "GET /ws HTTP/1.1\r\nHost: 127.0.0.1:" + std::to_string(port) +
                              "\r\nUpgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n"
                              "Sec-WebSocket-Version: 13\r\nOrigin: " + origin + "\r\n\r\n", 10s);
  };
  auto evil = upgrade("http://evil.example");
  CHECK(evil.status == 403);
  CHECK(evil.body.find("WebSocket from another origin (http://evil.example) refused") != std::string::npos);
  CHECK(upgrade("http://127.0.0.1:" + std::to_string(port)).status == 101);
  // DNS rebinding: a page of evil.example whose name now resolves to this address sends Host
  // and Origin that agree, both evil.example:PORT. Refused on /ws (it was upgraded before, and
  // its reads worked), /api and /metrics; the panel's own files stay public.
  const std::string evil_host = "evil.example:" + std::to_string(port);
  auto rebound_ws = http_raw(port, "GET /ws HTTP/1.1\r\nHost: " + evil_host +
                                       "\r\nUpgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n"
                                       "Sec-WebSocket-Version: 13\r\nOrigin: http://" + evil_host + "\r\n\r\n", 10s);
  CHECK(rebound_ws.status == 403);
  CHECK(rebound_ws.body.find("Host " + evil_host + " is not a name of this panel") != std::string::npos);
  const std::string status_req = json{{"id", 1}, {"cmd", "status"}}.dump();
  auto post = [&](const std::string& host, const std::string& origin) {
    return http_raw(port, "POST /api HTTP/1.1\r\nHost: " + host + "\r\n" + (origin.empty() ? "" : "Origin: " + origin + "\r\n") +
                              "Connection: close\r\nContent-Type: text/plain\r\nContent-Length: " +
                              std::to_string(status_req.size()) + "\r\n\r\n" + status_req);
  };
  CHECK(post(evil_host, "http://" + evil_host).status == 403);
  CHECK(post(evil_host, "").status == 403);
  // A cross-site form posted to /api from the operator's browser: its Origin is not the Host.
  const std::string own = "127.0.0.1:" + std::to_string(port);
  auto csrf = post(own, "http://evil.example");
  CHECK(csrf.status == 403);
  CHECK(csrf.body.find("request from another origin (http://evil.example) refused") != std::string::npos);
  CHECK(post(own, "http://" + own).status == 200);
  CHECK(post("localhost:" + std::to_string(port), "").status == 200);
  CHECK(http_raw(port, "GET /metrics HTTP/1.1\r\nHost: " + evil_host + "\r\nConnection: close\r\n\r\n").status == 403);
  CHECK(http_raw(port, "GET / HTTP/1.1\r\nHost: " + evil_host + "\r\nConnection: close\r\n\r\n").status == 200);

  // WebSocket garbage: a bad line is an error reply and the connection stays; a binary message
  // is refused the same way; a message over 1 MiB closes the connection.
  {
    WsClient ws("127.0.0.1", port, "/ws");
    REQUIRE(ws.ok());
    REQUIRE(ws.read());  // hello
    REQUIRE(ws.send("{oops"));
    auto r = json::parse(ws.read().value_or("null"), nullptr, false);
    CHECK(code_of(r) == "bad_json");
    REQUIRE(ws.send("\x01\x02\x03", true));
    r = json::parse(ws.read().value_or("null"), nullptr, false);
    CHECK(code_of(r) == "bad_request");
    CHECK(r["error"]["message"].get<std::string>().find("binary message") != std::string::npos);
    CHECK(code_of(ws.call({{"cmd", "status"}})) == "ok");
    ws.send(std::string(2u << 20, ' '));
    CHECK(!ws.read(20s));  // closed
  }
  still_serving(bench, port);
}

TEST_CASE("a non-loopback web.listen without allow_remote keeps fogbenchd from starting, naming the field") {
  require_sim();
  char tmpl[] = "/tmp/fogbench-web-XXXXXX";
  const std::filesystem::path dir = ::mkdtemp(tmpl);
  json c = {{"simulated", true}, {"storage", {{"path", "s.db"}}}, {"socket", {{"path", "d.sock"}}},
            {"chamber_limits", {{"min_c", -30}, {"max_c", 60}, {"max_rate_c_per_min", 3}}}, {"profile_dir", "."},
            {"web", {{"listen", "0.0.0.0:8080"}}}};
  std::ofstream(dir / "c.json") << c.dump();
  Process p({(kBin / "fogbenchd").string(), "--config", (dir / "c.json").string()}, dir / "log");
  CHECK(p.read_line(30s).empty());  // no ready line
  CHECK(p.wait(30s) == 2);
  const std::string log = slurp(dir / "log");
  INFO(log);
  // The key, its line in the file (the start-up reads it as --check-config and a reload do), the reason.
  CHECK(log.find("web.listen (line 1): 0.0.0.0 is not a loopback address") != std::string::npos);
  std::filesystem::remove_all(dir);
}
