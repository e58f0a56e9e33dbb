// The handler with its long commands on an offload that the test holds (issue 11, point 5): a
// fit or a page of samples waiting for the worker does not hold up another session's status,
// its reply comes once the job has run, and a job reads what the jobs before it stored. The
// hold is a gate the test opens, not a timing: nothing here measures time.
#include <deque>

#include "fixture.hpp"

#include "fogbench/daemon/handler.hpp"
#include "fogbench/daemon/offload.hpp"

using namespace fogbench;
using namespace fogbench::daemon;
using namespace fogbench::daemon::test;
using nlohmann::json;

namespace {

// Jobs wait until the test releases them, oldest first; each then runs with its continuation,
// as fogbenchd's worker and then its loop would run them.
class HeldOffload final : public Offload {
 public:
  explicit HeldOffload(storage::Store& store) : store_(store) {}
  void submit(Job job) override { jobs_.push_back(std::move(job)); }
  std::size_t held() const { return jobs_.size(); }
  void release_one() {
    REQUIRE(!jobs_.empty());
    Job job = std::move(jobs_.front());
    jobs_.pop_front();
    if (Then then = job(store_)) then();
  }

 private:
  storage::Store& store_;
  std::deque<Job> jobs_;
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
