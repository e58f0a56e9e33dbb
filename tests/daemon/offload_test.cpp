// The handler with its long commands on an offload that the test holds (issue 11, point 5): a
// fit or a page of samples waiting for the worker does not hold up another session's status,
// its reply comes once the job has run, and a job reads what the jobs before it stored. The
// hold is a gate the test opens, not a timing: nothing here measures time.
#include <deque>

#include "fixture.hpp"

#include "fogbench/daemon/handler.hpp"
#include "fogbench/daemon/offload.hpp"
#include "fogbench/storage/models.hpp"

using namespace fogbench;
using namespace fogbench::daemon;
using namespace fogbench::daemon::test;
using nlohmann::json;

namespace {

// Jobs wait until the test releases them, in fogbenchd's worker's order (JobQueue: the
// station's, then the local operator's, then the network's, each oldest first); each then runs
// with its continuation, as fogbenchd's worker and then its loop would run them.
class HeldOffload final : public Offload {
 public:
  explicit HeldOffload(storage::Store& store) : store_(store) {}
  void submit(Job job, JobOrigin origin) override {
    queue_.push(std::move(job), std::move(origin));
    ++held_;
  }
  std::size_t pending_from(std::string_view address) const override { return queue_.pending_from(address); }
  std::size_t held() const { return held_; }
  void release_one() {
    auto next = queue_.pop();
    REQUIRE(next.has_value());
    --held_;
    Then then = next->job(store_);
    queue_.done(next->address);
    if (then) then();
  }

 private:
  storage::Store& store_;
  JobQueue queue_;
  std::size_t held_ = 0;
};

struct Rig {
  storage::Store store = memory_store();
  Station station{golden_config(), store};
  HeldOffload offload{store};
  Handler handler{station};
  Rig() { station.set_offload(&offload); }
  // Sends a line on a session; its replies are appended to `out` whenever they come.
  void send(const std::string& line, SessionState& s, std::vector<json>& out) {
    handler.handle_line(line, s, [&out](Handler::Line l) {
      REQUIRE(!l->empty());
      CHECK(l->back() == '\n');  // one protocol line
      out.push_back(json::parse(*l));
    });
  }
};

std::optional<std::int64_t> current_model_id(storage::Store& store, const std::string& serial) {
  auto m = store.current_model(serial);
  REQUIRE(m.has_value());
  if (!*m) return std::nullopt;
  return (*m)->id;
}

}  // namespace

TEST_CASE("offload: a fit held on the worker does not hold up status, and its reply comes when it has run") {
  Rig r;
  SessionState a, b;
  std::vector<json> ra, rb;
  SyntheticBench bench(1);
  double clock_s = 0.0;
  r.send(R"({"id":1,"cmd":"run.start","profile":"short","units":["FOG-0001"]})", a, ra);
  REQUIRE(ra.size() == 1);  // answered at once: run.start is not offloaded
  REQUIRE(ra[0].contains("result"));
  run_to_end(r.station, bench, clock_s);
  // The run completed; its automatic fit is the first job, held: nothing stored yet.
  CHECK(r.station.status()["last_run"]["state"] == "completed");
  CHECK(r.offload.held() == 1);
  CHECK(!current_model_id(r.store, "FOG-0001"));

  // A fit asked meanwhile waits behind it; a status on another session does not wait.
  r.send(R"({"id":2,"cmd":"model.fit","run_id":1,"method":"joint"})", a, ra);
  CHECK(ra.size() == 1);
  CHECK(r.offload.held() == 2);
  r.send(R"({"id":7,"cmd":"status"})", b, rb);
  REQUIRE(rb.size() == 1);
  CHECK(rb[0]["id"] == 7);
  CHECK(rb[0]["result"]["run"].is_null());

  // The automatic fit runs and stores model 1 (the model.fit is still held: no reply yet).
  r.offload.release_one();
  CHECK(current_model_id(r.store, "FOG-0001") == 1);
  CHECK(ra.size() == 1);
  // The model.fit runs after it and reads what it stored: model 2, whose parent is model 1.
  r.offload.release_one();
  REQUIRE(ra.size() == 2);
  CHECK(ra[1]["id"] == 2);
  REQUIRE(ra[1].contains("result"));
  CHECK(ra[1]["result"]["version"] == 2);
  CHECK(ra[1]["result"]["parent_id"] == 1);
  CHECK(ra[1]["result"]["method"] == "joint");
  CHECK(r.offload.held() == 0);

  // Both are in the run's audit trail: the automatic fit's note, then the operator's command.
  auto d = r.store.get_run(1);
  REQUIRE(d.has_value());
  bool note = false, command = false;
  for (const auto& e : d->events) {
    const json detail = json::parse(e.detail_json);
    if (e.kind == storage::EventKind::note && detail.value("analysis", "") == "fit") note = detail["ok"] == true;
    if (e.kind == storage::EventKind::command && detail.value("cmd", "") == "model.fit") command = note;
  }
  CHECK(note);
  CHECK(command);
}

TEST_CASE("offload: run.samples and run.get are answered from the worker, errors included, in the order sent") {
  Rig r;
  SessionState a, b;
  std::vector<json> ra, rb;
  SyntheticBench bench(2);
  r.send(R"({"id":1,"cmd":"run.start","profile":"short","units":["FOG-0001","FOG-0002"]})", a, ra);
  for (int i = 0; i < 30; ++i) r.station.tick(i, bench.step(20));
  r.send(R"({"id":2,"cmd":"run.samples","run_id":1,"unit":"FOG-0002","offset":10,"limit":5})", a, ra);
  r.send(R"({"id":3,"cmd":"run.get","run_id":1})", a, ra);
  r.send(R"({"id":4,"cmd":"run.samples","run_id":1,"unit":"FOG-0009"})", a, ra);
  // Arguments are checked on the loop: a bad one is answered at once, with nothing held.
  r.send(R"({"id":5,"cmd":"run.samples","run_id":1,"limit":10001})", b, rb);
  REQUIRE(rb.size() == 1);
  CHECK(rb[0]["error"]["code"] == "bad_request");
  CHECK(ra.size() == 1);
  REQUIRE(r.offload.held() == 3);

  // The run goes on while they wait: 10 more seconds stored before they are read.
  for (int i = 30; i < 40; ++i) r.station.tick(i, bench.step(20));
  while (r.offload.held() > 0) r.offload.release_one();
  REQUIRE(ra.size() == 4);
  CHECK(ra[1]["id"] == 2);
  CHECK(ra[1]["result"]["total"] == 40);  // read when the job ran
  REQUIRE(ra[1]["result"]["samples"].size() == 5);
  CHECK(ra[1]["result"]["samples"][0]["t_s"] == 10.0);
  CHECK(ra[2]["id"] == 3);
  // run.get of the active run: its live quality counters, taken on the loop when it was asked.
  CHECK(ra[2]["result"]["quality"].is_array());
  CHECK(ra[2]["result"]["samples"] == json::array({40, 40}));
  CHECK(ra[3]["id"] == 4);
  CHECK(ra[3]["error"]["code"] == "not_found");
}

TEST_CASE("offload: the job queue serves the station, then the local operator, then the network, each in order") {
  JobQueue q;
  std::vector<std::string> ran;
  auto job = [&ran](std::string name) {
    return [&ran, name](storage::Store&) -> Offload::Then {
      ran.push_back(name);
      return {};
    };
  };
  q.push(job("remote 1"), {JobClass::remote, "10.0.0.1"});
  q.push(job("local 1"), {JobClass::local, {}});
  q.push(job("remote 2"), {JobClass::remote, "10.0.0.2"});
  q.push(job("station 1"), {JobClass::station, {}});
  q.push(job("remote 3"), {JobClass::remote, "10.0.0.1"});
  q.push(job("local 2"), {JobClass::local, {}});
  CHECK(q.pending_from("10.0.0.1") == 2);
  CHECK(q.pending_from("10.0.0.2") == 1);
  CHECK(q.pending_from("10.0.0.3") == 0);
  storage::Store store = memory_store();
  std::vector<std::string> addresses;
  while (auto next = q.pop()) {
    next->job(store);
    addresses.push_back(next->address);
  }
  CHECK(q.empty());
  CHECK(ran == std::vector<std::string>{"station 1", "local 1", "local 2", "remote 1", "remote 2", "remote 3"});
  // A popped job still counts for its address until it is done (it is running).
  CHECK(q.pending_from("10.0.0.1") == 2);
  for (const auto& a : addresses) q.done(a);
  CHECK(q.pending_from("10.0.0.1") == 0);
  CHECK(q.pending_from("10.0.0.2") == 0);
}

TEST_CASE("offload: a finished run's analysis goes before the network's waiting requests, and one address has a bounded share") {
  Rig r;
  SessionState local;
  std::vector<json> rl;
  // Network clients: read-only, from one address (socket.max_analyses_per_address is 4).
  std::vector<SessionState> remote(6);
  std::vector<std::vector<json>> rr(6);
  for (auto& s : remote) {
    s.may_control = false;
    s.address = "192.0.2.7";
  }
  SyntheticBench bench(1);
  double clock_s = 0.0;
  r.send(R"({"id":1,"cmd":"run.start","profile":"short","units":["FOG-0001"]})", local, rl);
  REQUIRE(rl.size() == 1);
  for (; clock_s < 30.0; clock_s += 1.0) r.station.tick(clock_s, bench.step(20));
  // While the run records, the network asks for reads: four are queued, the fifth and sixth
  // are refused with the reason and the key.
  for (std::size_t i = 0; i < remote.size(); ++i)
    r.send(json{{"id", 10 + i}, {"cmd", "run.get"}, {"run_id", 1}}.dump(), remote[i], rr[i]);
  CHECK(r.offload.held() == 4);
  for (std::size_t i = 0; i < 4; ++i) CHECK(rr[i].empty());
  for (std::size_t i = 4; i < 6; ++i) {
    REQUIRE(rr[i].size() == 1);
    CHECK(rr[i][0]["error"]["code"] == "busy");
    CHECK_THAT(rr[i][0]["error"]["message"].get<std::string>(), Catch::Contains("192.0.2.7"));
    CHECK_THAT(rr[i][0]["error"]["message"].get<std::string>(), Catch::Contains("socket.max_analyses_per_address"));
  }
  // Another address is not counted against it.
  SessionState other;
  other.may_control = false;
  other.address = "192.0.2.8";
  std::vector<json> ro;
  r.send(R"({"id":20,"cmd":"run.get","run_id":1})", other, ro);
  CHECK(r.offload.held() == 5);

  // The run ends: its automatic fit is queued behind five network jobs, and runs first.
  run_to_end(r.station, bench, clock_s);
  REQUIRE(r.station.status()["last_run"]["state"] == "completed");
  CHECK(r.offload.held() == 6);
  CHECK(!current_model_id(r.store, "FOG-0001"));
  r.offload.release_one();
  CHECK(current_model_id(r.store, "FOG-0001") == 1);
  for (std::size_t i = 0; i < 4; ++i) CHECK(rr[i].empty());
  // The local operator's request goes before the network's too.
  r.send(R"({"id":2,"cmd":"run.get","run_id":1})", local, rl);
  r.offload.release_one();
  REQUIRE(rl.size() == 2);
  CHECK(rl[1]["id"] == 2);
  for (std::size_t i = 0; i < 4; ++i) CHECK(rr[i].empty());
  // Then the network's, in the order sent; once one is answered, its address may send again.
  r.offload.release_one();
  REQUIRE(rr[0].size() == 1);
  CHECK(rr[0][0]["id"] == 10);
  CHECK(rr[0][0].contains("result"));
  r.send(R"({"id":30,"cmd":"run.get","run_id":1})", remote[4], rr[4]);
  CHECK(rr[4].size() == 1);  // queued, not refused
  while (r.offload.held() > 0) r.offload.release_one();
  for (std::size_t i = 1; i < 4; ++i) CHECK(rr[i].size() == 1);
  REQUIRE(rr[4].size() == 2);
  CHECK(rr[4][1]["id"] == 30);
  CHECK(ro.size() == 1);
}
