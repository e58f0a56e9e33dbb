// The fair loop against the live daemon (issue 11, point 5): a client that asks and does not
// read is not served further until it has read (its output stays bounded, its requests wait,
// in order), other clients are served meanwhile, and pipelined requests that go to the analysis
// worker keep their order among those answered at once.
#include "live_bench.hpp"

using namespace fogbench::daemon::test;
using namespace fogbench::daemon::test::live;

TEST_CASE("e2e fair loop: a client that does not read waits with its requests unserved, then gets them all in order") {
  REQUIRE(have_sim());
  LiveBench bench(20.0);
  LineClient c(bench.socket());
  REQUIRE(c.ok());
  const auto run = bench.start_run(c, "short", {"SIM-0001"});

  // 3,000 status requests (some 800 bytes of reply each: 2.4 MB, far more than the 256 KiB the
  // daemon queues for a connection plus what the kernel buffers), then a run.abort, and nothing
  // read. Before the fix all of them were answered at once into the connection's queue, and the
  // abort ended the run.
  LineClient deaf(bench.socket());
  REQUIRE(deaf.ok());
  REQUIRE(deaf.line(10s));  // hello
  constexpr int kAsks = 3000;
  std::string asks;
  for (int i = 1; i <= kAsks; ++i) asks += R"({"id":)" + std::to_string(i) + R"(,"cmd":"status"})" "\n";
  asks += R"({"id":)" + std::to_string(kAsks + 1) + R"(,"cmd":"run.abort","reason":"deaf"})" "\n";
  std::thread writer([&] { deaf.send_raw(asks); });  // blocks while the daemon does not read

  // Meanwhile the others are served, and the abort stays unserved while the client does not read
  // (2 s of it: within the 10 s after which a stuck write drops a client).
  for (int i = 0; i < 20; ++i) {
    auto s = c.call({{"cmd", "status"}}, 10s);
    REQUIRE(code_of(s) == "ok");
    REQUIRE(s["result"]["run"].is_object());
    CHECK(s["result"]["run"]["id"] == run);
    std::this_thread::sleep_for(100ms);
  }

  // Now it reads: every reply, in order, the abort last; then the run is aborted.
  int replies = 0, last_id = 0;
  bool in_order = true;
  json abort_reply;
  while (replies < kAsks + 1) {
    auto l = deaf.line(30s);
    if (!l) break;
    auto j = json::parse(*l, nullptr, false);
    if (j.value("type", "") != "reply") continue;
    ++replies;
    in_order = in_order && j["id"].get<int>() == last_id + 1;
    last_id = j["id"].get<int>();
    if (last_id == kAsks + 1) abort_reply = j;
  }
  writer.join();
  CHECK(replies == kAsks + 1);
  CHECK(in_order);
  CHECK(code_of(abort_reply) == "ok");
  auto g = bench.wait_state(c, run, {"aborted"}, 30s);
  CHECK(g["result"]["run"]["state"] == "aborted");
  CHECK(g["result"]["run"]["reason"] == "aborted by operator: deaf");
}

TEST_CASE("e2e fair loop: requests answered by the analysis worker keep their order among the others") {
  REQUIRE(have_sim());
  LiveBench bench(20.0);
  LineClient c(bench.socket());
  REQUIRE(c.ok());
  const auto run = bench.start_run(c, "short", {"SIM-0001"});
  bench.wait_status(c, [](const json& r) { return r["run"].is_object() && r["run"]["elapsed_s"].get<double>() > 20; },
                    60s);
  // Pipelined: pages of samples (the worker), status and run.list (the loop), run.get (the worker).
  std::string batch;
  const std::vector<std::string> cmds = {"run.samples", "status", "run.get", "run.list", "run.samples", "status"};
  for (int round = 0; round < 20; ++round)
    for (std::size_t k = 0; k < cmds.size(); ++k) {
      json q = {{"id", round * 100 + static_cast<int>(k)}, {"cmd", cmds[k]}};
      if (cmds[k] == "run.samples" || cmds[k] == "run.get") q["run_id"] = run;
      if (cmds[k] == "run.samples") q["limit"] = 10000;
      batch += q.dump() + "\n";
    }
  REQUIRE(c.send_raw(batch));
  std::vector<int> ids;
  while (ids.size() < 20 * cmds.size()) {
    auto l = c.line(30s);
    if (!l) break;
    auto j = json::parse(*l, nullptr, false);
    if (j.value("type", "") != "reply") continue;
    CHECK(code_of(j) == "ok");
    ids.push_back(j["id"].get<int>());
  }
  REQUIRE(ids.size() == 20 * cmds.size());
  for (std::size_t i = 0; i < ids.size(); ++i)
    CHECK(ids[i] == static_cast<int>(i / cmds.size()) * 100 + static_cast<int>(i % cmds.size()));
  CHECK(code_of(c.call({{"cmd", "run.abort"}})) == "ok");
}
