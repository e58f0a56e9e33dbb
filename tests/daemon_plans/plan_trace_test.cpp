// Traceability of plans (issue 24, docs/plans.md): the operator and the units' lots given to
// plan.start and queue.add are stored with the plan, shown by plan.status and queue.list, and
// given to every run the plan starts (each run's identity names the operator, each unit its
// lot), the operator defaulting to the unix peer's user as run.start's; bad values are refused
// naming the field; the certificate of a unit a plan qualified names both. fogbenchd and
// fogbench-sim as processes (K = 100) with short profiles; fogctl for its flags.
#include "../daemon/live_bench.hpp"
#include "plan_wait.hpp"
#include "fogbench/storage/plans.hpp"

#include <pwd.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fstream>
#include <sstream>

using namespace fogbench::daemon::test;
using namespace fogbench::daemon::test::live;

namespace {

json plan_req(const std::string& cmd, const std::string& text, const std::vector<std::string>& units) {
  return {{"cmd", cmd}, {"text", text}, {"source", "t.plan"}, {"units", units}};
}

// Every run of the finished plan: its identity's operator and each unit's lot, from run.get.
struct RunTrace {
  std::string op, source;
  std::map<std::string, json> lots;  // serial -> lot (null: none)
};
std::vector<RunTrace> run_traces(LineClient& c, const json& status) {
  std::vector<RunTrace> out;
  for (const auto& r : status["result"]["progress"]["runs"]) {
    auto g = c.call({{"cmd", "run.get"}, {"run_id", r["run_id"]}});
    INFO(g.dump());
    REQUIRE(code_of(g) == "ok");
    RunTrace t;
    t.op = g["result"]["identity"]["operator"].get<std::string>();
    t.source = g["result"]["identity"]["operator_source"].get<std::string>();
    const json& run = g["result"]["run"];
    for (std::size_t i = 0; i < run["units"].size(); ++i) t.lots[run["units"][i].get<std::string>()] = run["lots"][i];
    out.push_back(std::move(t));
  }
  return out;
}

std::string my_user() {
  const passwd* pw = ::getpwuid(::getuid());
  return pw && pw->pw_name ? pw->pw_name : "uid " + std::to_string(::getuid());
}

std::string slurp(const std::filesystem::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

struct Out {
  int code = -1;
  std::string out, err;
};
Out fogctl(const LiveBench& bench, const std::string& args) {
  const auto out = bench.dir / "fogctl.out", err = bench.dir / "fogctl.err";
  const std::string cmd = "cd '" + bench.dir.string() + "' && env -u FOGBENCH_TOKEN '" + (kBin / "fogctl").string() +
                          "' " + args + " --socket '" + bench.socket().string() + "' >'" + out.string() + "' 2>'" +
                          err.string() + "'";
  const int st = std::system(cmd.c_str());
  Out o;
  o.code = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
  o.out = slurp(out);
  o.err = slurp(err);
  return o;
}

const char* kFitVerify = "plan traced\nstep pfit fit\nstep pver verify\n";

}  // namespace

TEST_CASE("plan trace: plan start --operator --lot gives every run the operator and every unit its lot, and the certificate names both") {
  require_sim();
  require_fogctl();
  LiveBench bench(100.0, json::object(), true);
  INFO("test dir " << bench.dir);
  // A fit run of 40 min and a verify run of 25 min (at K = 100: under a minute together).
  std::ofstream(bench.dir / "profiles" / "pfit.profile")
      << "setpoint 20 C\nhold 5 min\nramp to 30 C at 1 C/min\nhold 10 min\nramp to 20 C at 1 C/min\nhold 5 min\n";
  std::ofstream(bench.dir / "profiles" / "pver.profile")
      << "setpoint 20 C\nhold 5 min\nramp to 25 C at 1 C/min\nhold 5 min\nramp to 20 C at 1 C/min\nhold 5 min\n";
  std::ofstream(bench.dir / "traced.plan") << kFitVerify;

  // fogctl's flags: --operator, one --lot per serial.
  auto st = fogctl(bench, "plan start traced.plan --unit SIM-0001 --unit SIM-0002 --operator 'Ada Lovelace' "
                          "--lot SIM-0001=LOT-A --lot SIM-0002=LOT-B --json");
  INFO(st.out << st.err);
  REQUIRE(st.code == 0);
  const json started = json::parse(st.out);
  CHECK(started["operator"] == "Ada Lovelace");
  CHECK(started["lots"] == json({{"SIM-0001", "LOT-A"}, {"SIM-0002", "LOT-B"}}));
  const auto plan_id = started["plan_id"].get<std::int64_t>();

  LineClient c(bench.socket());
  REQUIRE(c.ok());
  json done = wait_plan(c, plan_id, {"completed", "aborted", "failed"}, 600s);
  INFO(done.dump(1));
  REQUIRE(done["result"]["state"] == "completed");
  CHECK(done["result"]["operator"] == "Ada Lovelace");
  CHECK(done["result"]["operator_source"] == "client");
  CHECK(done["result"]["lots"]["SIM-0002"] == "LOT-B");
  const auto runs = run_traces(c, done);
  REQUIRE(runs.size() == 2);
  for (const auto& r : runs) {
    CHECK(r.op == "Ada Lovelace");
    CHECK(r.source == "client");
    CHECK(r.lots.at("SIM-0001") == "LOT-A");
    CHECK(r.lots.at("SIM-0002") == "LOT-B");
  }
  // The plan's audit trail names them too.
  {
    fogbench::storage::OpenOptions ro;
    ro.read_only = true;
    auto store = fogbench::storage::Store::open(bench.dir / "fogbench.db", ro);
    REQUIRE(store.has_value());
    auto events = store->plan_events(plan_id);
    REQUIRE(events.has_value());
    bool seen = false;
    for (const auto& e : *events)
      if (e.kind == "plan.start") {
        const json d = json::parse(e.detail_json);
        CHECK(d["operator"] == "Ada Lovelace");
        CHECK(d["lots"]["SIM-0001"] == "LOT-A");
        seen = true;
      }
    CHECK(seen);
  }
  // The human table says who and which lots.
  auto human = fogctl(bench, "plan status " + std::to_string(plan_id));
  INFO(human.out << human.err);
  CHECK_THAT(human.out, Catch::Contains("operator Ada Lovelace, lots SIM-0001=LOT-A SIM-0002=LOT-B"));

  // The certificate of a unit the plan qualified: the operator and the unit's lot in its runs,
  // in the JSON and on the page.
  auto cert = c.call({{"cmd", "cert.get"}, {"serial", "SIM-0002"}});
  INFO(cert.dump());
  REQUIRE(code_of(cert) == "ok");
  const json& cruns = cert["result"]["certificate"]["runs"];
  REQUIRE(cruns.size() >= 2);
  for (const auto& r : cruns) {
    CHECK(r["identity"]["operator"] == "Ada Lovelace");
    bool lot_seen = false;
    for (const auto& u : r["identity"]["units"])
      if (u["serial"] == "SIM-0002") {
        CHECK(u["lot"] == "LOT-B");
        lot_seen = true;
      }
    CHECK(lot_seen);
  }
  auto page = fogctl(bench, "cert SIM-0002 -o cert.html");
  INFO(page.out << page.err);
  REQUIRE(page.code == 0);
  const std::string html = slurp(bench.dir / "cert.html");
  CHECK_THAT(html, Catch::Contains("<td>Ada Lovelace</td><td>LOT-B</td>"));

  // The CSV export of a run of the plan carries the unit's lot beside the operator.
  auto csv = fogctl(bench, "run export " + std::to_string(done["result"]["progress"]["runs"][0]["run_id"].get<std::int64_t>()) +
                               " --unit SIM-0002");
  INFO(csv.err);
  REQUIRE(csv.code == 0);
  CHECK_THAT(csv.out, Catch::Contains("# operator: Ada Lovelace\n") && Catch::Contains("# lot: LOT-B\n"));
}

TEST_CASE("plan trace: a queued plan keeps its operator and lot when it starts, the operator defaults to the peer's user") {
  require_sim();
  LiveBench bench(100.0, json::object(), true);
  INFO("test dir " << bench.dir);
  std::ofstream(bench.dir / "profiles" / "pshort.profile") << "setpoint 20 C\nhold 3 min\n";
  std::ofstream(bench.dir / "profiles" / "plong.profile") << "setpoint 20 C\nhold 300 min\n";
  LineClient c(bench.socket());
  REQUIRE(c.ok());
  // A run holds the chamber (3 min of wall time at K = 100), so both plans wait in the queue.
  auto hold = c.call({{"cmd", "run.start"}, {"profile", "plong"}, {"units", {"SIM-0001"}}});
  REQUIRE(code_of(hold) == "ok");
  json a = plan_req("queue.add", "plan named\nstep pshort soak\nstep pshort custom\n", {"SIM-0001", "SIM-0002"});
  a["operator"] = "Grace";
  a["lot"] = "L-2026-11";
  json ra = c.call(a);
  INFO(ra.dump());
  REQUIRE(code_of(ra) == "ok");
  json b = plan_req("queue.add", "plan peer\nstep pshort soak\n", {"SIM-0002"});
  json rb = c.call(b);
  INFO(rb.dump());
  REQUIRE(code_of(rb) == "ok");
  auto q = c.call({{"cmd", "queue.list"}});
  INFO(q.dump());
  REQUIRE(q["result"]["queue"].size() == 2);
  CHECK(q["result"]["queue"][0]["operator"] == "Grace");
  CHECK(q["result"]["queue"][0]["lots"] == json({{"SIM-0001", "L-2026-11"}, {"SIM-0002", "L-2026-11"}}));
  CHECK(q["result"]["queue"][1]["operator"] == my_user());
  CHECK(q["result"]["queue"][1]["operator_source"] == "peer");
  CHECK(q["result"]["queue"][1]["lots"] == json::object());
  REQUIRE(code_of(c.call({{"cmd", "run.abort"}, {"reason", "make way for the queue"}})) == "ok");

  json da = wait_plan(c, ra["result"]["plan_id"].get<std::int64_t>(), {"completed", "aborted", "failed"}, 300s);
  json db = wait_plan(c, rb["result"]["plan_id"].get<std::int64_t>(), {"completed", "aborted", "failed"}, 300s);
  INFO(da.dump() << db.dump());
  REQUIRE(da["result"]["state"] == "completed");
  REQUIRE(db["result"]["state"] == "completed");
  const auto ta = run_traces(c, da);
  REQUIRE(ta.size() == 2);
  for (const auto& r : ta) {
    CHECK(r.op == "Grace");
    CHECK(r.lots.at("SIM-0001") == "L-2026-11");
    CHECK(r.lots.at("SIM-0002") == "L-2026-11");
  }
  const auto tb = run_traces(c, db);
  REQUIRE(tb.size() == 1);
  CHECK(tb[0].op == my_user());
  CHECK(tb[0].source == "peer");
  CHECK(tb[0].lots.at("SIM-0002").is_null());
}

TEST_CASE("plan trace: a bad operator or lot is refused naming the field, and nothing is stored") {
  require_sim();
  require_fogctl();
  LiveBench bench(20.0);
  INFO("test dir " << bench.dir);
  std::ofstream(bench.dir / "profiles" / "pshort.profile") << "setpoint 20 C\nhold 3 min\n";
  std::ofstream(bench.dir / "s.plan") << "plan s\nstep pshort soak\n";
  LineClient c(bench.socket());
  REQUIRE(c.ok());
  const std::string text = "plan s\nstep pshort soak\n";
  struct Bad {
    const char* field;
    json value;
    const char* names;
  };
  const std::vector<Bad> bads = {
      {"operator", "Ada\x01", "operator:"},
      {"operator", std::string(65, 'x'), "operator:"},
      {"operator", 7, "operator:"},
      {"lot", "L\x1b[31m", "lot"},
      {"lot", std::string(65, 'l'), "lot"},
      {"lots", json({{"SIM-0002", "L\n1"}}), "lots.SIM-0002"},
      {"lots", json({{"SIM-0009", "L1"}}), "lots.SIM-0009"},
  };
  for (const char* cmd : {"plan.start", "queue.add"})
    for (const auto& b : bads) {
      json req = plan_req(cmd, text, {"SIM-0001", "SIM-0002"});
      req[b.field] = b.value;
      auto r = c.call(req);
      INFO(cmd << " " << req.dump() << " -> " << r.dump());
      CHECK(code_of(r) == "bad_request");
      CHECK_THAT(r["error"]["message"].get<std::string>(), Catch::StartsWith(b.names));
    }
  json both = plan_req("queue.add", text, {"SIM-0001"});
  both["lot"] = "A";
  both["lots"] = {{"SIM-0001", "B"}};
  CHECK(code_of(c.call(both)) == "bad_request");
  // fogctl refuses a bad name before sending, naming the field; a --lot it cannot read too.
  auto f = fogctl(bench, "plan start s.plan --unit SIM-0001 --operator \"$(printf 'Ada\\001')\"");
  CHECK(f.code == 2);
  CHECK_THAT(f.err, Catch::Contains("operator"));
  auto g = fogctl(bench, "queue add s.plan --unit SIM-0001 --lot A --lot B");
  CHECK(g.code == 2);
  CHECK_THAT(g.err, Catch::Contains("fogctl queue add: --lot"));
  // Nothing was stored or started.
  auto q = c.call({{"cmd", "queue.list"}});
  CHECK(q["result"]["queue"].empty());
  CHECK(q["result"]["running"].is_null());
  CHECK(code_of(c.call({{"cmd", "plan.status"}})) == "not_found");
}
