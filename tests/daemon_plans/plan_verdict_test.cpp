// One verdict per serial (issue 24 point 1) on the live mock bench: a plan stricter than the
// analysis settings fails a unit the settings would pass, and every place that shows the unit's
// verdict (plan.status, run.get, the certificate, its limits and their lines) shows the plan's,
// decided once and stored once.
#include "../daemon/live_bench.hpp"
#include "plan_wait.hpp"

#include <fstream>

using namespace fogbench::daemon::test;
using namespace fogbench::daemon::test::live;

namespace {

// A fit step and a verify step; comp_raw must be under 0.001 (the analysis settings say 0.2),
// and the fit's model must have a firmware form (judged, marginal when not).
const char* kStrict =
    "plan strict\n"
    "step vfit fit\n"
    "step vver verify\n"
    "limit comp_raw < 0.001 stop\n"
    "limit firmware required continue\n";

}  // namespace

TEST_CASE("plan verdict e2e: a plan's stricter limit fails the unit, and the certificate, run get and plan status all say fail by the plan") {
  require_sim();
  json sim = {{"units", {{{"serial", "SIM-0001"}}, {{"serial", "SIM-0002"}}}}};
  LiveBench bench(100.0, json::object(), true, sim);
  INFO("test dir " << bench.dir);
  std::ofstream(bench.dir / "profiles" / "vfit.profile")
      << "setpoint 20 C\nhold 10 min\nramp to 30 C at 1 C/min\nhold 15 min\nramp to 20 C at 1 C/min\nhold 15 min\n";
  std::ofstream(bench.dir / "profiles" / "vver.profile")
      << "setpoint 20 C\nhold 5 min\nramp to 25 C at 1 C/min\nhold 10 min\nramp to 20 C at 1 C/min\nhold 5 min\n";
  LineClient c(bench.socket());
  REQUIRE(c.ok());
  REQUIRE(json::parse(*c.line(10s))["type"] == "hello");

  json s = c.call({{"cmd", "plan.start"}, {"text", kStrict}, {"source", "strict.plan"}, {"units", {"SIM-0001", "SIM-0002"}}});
  INFO(s.dump());
  REQUIRE(code_of(s) == "ok");
  const auto plan_id = s["result"]["plan_id"].get<std::int64_t>();
  json done = wait_plan(c, plan_id, {"completed", "aborted", "failed"}, 600s);
  INFO(done.dump(1));
  REQUIRE(done["result"]["state"] == "completed");
  const json& unit = done["result"]["progress"]["units"][0];
  CHECK(unit["verdict"] == "fail");
  const auto& runs = done["result"]["progress"]["runs"];
  REQUIRE(runs.size() == 2);
  const auto verify_run = runs[1]["run_id"].get<std::int64_t>();

  // The firmware limit was judged at the fit: 1 (a firmware form) or 0 with the reason.
  bool firmware_judged = false;
  for (const auto& m : unit["measurements"])
    if (m["measurement"] == "firmware") {
      firmware_judged = true;
      CHECK(m["limit"] == "firmware required");
      CHECK(m["line"] == 5);
      CHECK((m["value"] == 1.0 || m["value"] == 0.0));
      CHECK(m["met"] == (m["value"] == 1.0));
      if (m["value"] == 0.0) CHECK(m.contains("note"));
    }
  CHECK(firmware_judged);

  // The verification itself met the analysis settings (0.2): a second verdict would say pass.
  json got = c.call({{"cmd", "run.get"}, {"run_id", verify_run}});
  REQUIRE(code_of(got) == "ok");
  REQUIRE(got["result"]["verifications"].size() == 2);
  CHECK(got["result"]["verifications"][0]["pass"] == true);
  // run.get shows the one verdict: the plan's fail, with its rule.
  REQUIRE(got["result"]["verdicts"].size() == 2);
  const json& rv = got["result"]["verdicts"][0];
  CHECK(rv["verdict"] == "fail");
  CHECK(rv["rule"] == "plan");
  CHECK(rv["plan"]["name"] == "strict");
  CHECK(rv["plan"]["id"] == plan_id);
  // The fit run, a step of the same plan, points to the same decision.
  json fit = c.call({{"cmd", "run.get"}, {"run_id", runs[0]["run_id"]}});
  CHECK(fit["result"]["verdicts"][0]["verdict_id"] == rv["verdict_id"]);

  // The certificate: fail, decided by the plan, with its limits, their lines and the values.
  json cert = c.call({{"cmd", "cert.get"}, {"serial", "SIM-0001"}});
  REQUIRE(code_of(cert) == "ok");
  const json& ct = cert["result"]["certificate"];
  CHECK(ct["verdict"] == "fail");
  CHECK(ct["qualification"]["verdict_id"] == rv["verdict_id"]);
  CHECK(ct["qualification"]["rule"] == "plan");
  CHECK(ct["qualification"]["plan"]["name"] == "strict");
  CHECK(ct["qualification"]["plan"]["sha256"].get<std::string>().size() == 64);
  bool comp_raw_listed = false;
  for (const auto& l : ct["qualification"]["limits"])
    if (l["measurement"] == "comp_raw") {
      comp_raw_listed = true;
      CHECK(l["limit"] == "comp_raw < 0.001");
      CHECK(l["line"] == 4);
      CHECK(l["met"] == false);
      CHECK(l["value"].get<double>() < 0.2);
    }
  CHECK(comp_raw_listed);
  // Issued again now: the same facts, the same certificate (nothing recomputed differently).
  CHECK(cert["result"]["issued_now"] == false);
}
