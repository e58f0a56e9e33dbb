// The command sockets against the real fogbenchd: the unix socket's mode and group, TCP that
// reads without a token and controls only with it, and clients that misbehave (a flood of
// pipelined requests, one that never reads) without disturbing a run.
#include "live_bench.hpp"

#include <grp.h>
#include <sys/stat.h>

using namespace fogbench::daemon::test;
using namespace fogbench::daemon::test::live;
using nlohmann::json;
using namespace std::chrono_literals;

namespace {


const std::string kToken = "e2e-token-0123456789";

}  // namespace

TEST_CASE("e2e sockets: the unix socket is 0660 in socket.group, TCP reads freely and controls with the token") {
  require_sim();
  const ::group* g = ::getgrgid(::getgid());
  REQUIRE(g != nullptr);
  const std::string group = g->gr_name;
  const auto port = free_port();
  LiveBench bench(20.0, {{"socket", {{"group", group}, {"tcp", {{"port", port}, {"token", kToken}}}}}});
  struct stat st{};
  REQUIRE(::stat(bench.socket().c_str(), &st) == 0);
  CHECK((st.st_mode & 0777) == 0660);
  CHECK(st.st_gid == g->gr_gid);

  LineClient tcp(port);
  REQUIRE(tcp.ok());
  CHECK(code_of(tcp.call({{"cmd", "status"}})) == "ok");
  CHECK(code_of(tcp.call({{"cmd", "run.list"}})) == "ok");
  CHECK(code_of(tcp.call({{"cmd", "run.start"}, {"profile", "short"}, {"units", {"SIM-0001"}}})) == "forbidden");
  CHECK(code_of(tcp.call({{"cmd", "run.start"}, {"profile", "short"}, {"units", {"SIM-0001"}}, {"token", "guess"}})) ==
        "forbidden");
  CHECK(code_of(tcp.call({{"cmd", "run.start"}, {"profile", "short"}, {"units", {"SIM-0001"}}, {"token", kToken}})) ==
        "ok");
  CHECK(code_of(tcp.call({{"cmd", "run.abort"}, {"token", kToken}})) == "ok");
}

TEST_CASE("e2e sockets: 10,000 pipelined requests are all answered, a client that never reads is dropped, the run goes on") {
  require_sim();
  LiveBench bench(20.0);
  LineClient c(bench.socket());
  REQUIRE(c.ok());
  const auto run = bench.start_run(c, "short", {"SIM-0001"});

  // A client that asks and never reads: it is served until 256 KiB of replies are queued for it,
  // then its requests wait, and it is dropped once a write has been stuck for 10 s.
  LineClient deaf(bench.socket());
  REQUIRE(deaf.ok());
  {
    std::string asks;
    for (int i = 1; i <= 40000; ++i) asks += R"({"id":)" + std::to_string(i) + R"(,"cmd":"status"})" "\n";
    deaf.send_raw(asks);  // false once the daemon has closed it: either way it is done
  }

  // The flood: every request written before any reply is read, a reader on the side so that
  // neither end blocks on a full buffer.
  LineClient flood(bench.socket());
  REQUIRE(flood.ok());
  constexpr int kRequests = 10000;
  std::string batch;
  for (int i = 1; i <= kRequests; ++i) batch += R"({"id":)" + std::to_string(i) + R"(,"cmd":"run.list","limit":1})" "\n";
  std::thread writer([&] { flood.send_raw(batch); });
  int replies = 0, last_id = 0;
  bool in_order = true;
  while (replies < kRequests) {
    auto l = flood.line(60s);
    if (!l) break;
    auto j = json::parse(*l, nullptr, false);
    if (j.value("type", "") != "reply") continue;
    ++replies;
    in_order = in_order && j["id"].get<int>() == last_id + 1;
    last_id = j["id"].get<int>();
  }
  writer.join();
  CHECK(replies == kRequests);
  CHECK(in_order);

  // Meanwhile the run went on, every second stored.
  auto s = bench.wait_status(c, [](const json& r) { return r["run"].is_object() && r["run"]["elapsed_s"].get<double>() > 30; }, 60s);
  REQUIRE(s["result"]["run"].is_object());
  CHECK(s["result"]["run"]["id"] == run);
  CHECK(s["result"]["run"]["state"] == "running");
  CHECK(code_of(c.call({{"cmd", "run.abort"}})) == "ok");
  auto g = c.call({{"cmd", "run.get"}, {"run_id", run}});
  auto page = c.call({{"cmd", "run.samples"}, {"run_id", run}, {"limit", 10000}});
  double prev = -1;
  for (const auto& smp : page["result"]["samples"]) {
    CHECK(smp["t_s"].get<double>() == prev + 1);
    prev = smp["t_s"].get<double>();
  }
  CHECK(page["result"]["total"] == g["result"]["samples"][0]);

  // The deaf client was closed: what the kernel buffered, then the end.
  const auto deadline = SteadyClock::now() + 60s;
  while (!deaf.closed() && SteadyClock::now() < deadline) (void)deaf.line(1s);
  CHECK(deaf.closed());
}
