// A plan's limits judged on every axis of a three-axis unit (issue 29 point 3), on the live mock
// bench: y drifts with T1 alone (fogbench-sim --axis-effect y=0.5*T1), which the paper's model
// cannot compensate, so a plan whose comp_raw limit x and z meet fails the unit on y, names y in
// its reasons, and the unit's one verdict (plan.status, run.get, the certificate, fogctl) is the
// plan's, with each axis' evidence. A one-axis unit's plans are unchanged (plan_verdict_test.cpp,
// the golden transcripts).
#include "../daemon/live_bench.hpp"
#include "plan_wait.hpp"

#include <sys/wait.h>

#include <fstream>
#include <sstream>

using namespace fogbench::daemon::test;
using namespace fogbench::daemon::test::live;

namespace {

const char* kAxesPlan =
    "plan axes\n"
    "step exp1 fit\n"
    "step exp2 verify\n"
    "limit comp_raw < 0.2 stop\n";

// The entry of `list` whose `key` holds `value` (null when none does).
json plan_axes_entry(const json& list, const char* key, const json& value) {
  for (const auto& e : list)
    if (e.is_object() && e.contains(key) && e[key] == value) return e;
  return nullptr;
}

// fogctl with `args` against the bench: its exit code and what it printed.
std::pair<int, std::string> plan_axes_fogctl(const LiveBench& bench, const std::string& args) {
  const auto out = bench.dir / "fogctl-plan-axes.out";
  const std::string cmd = "cd '" + bench.dir.string() + "' && env -u FOGBENCH_TOKEN '" + (kBin / "fogctl").string() + "' " +
                          args + " --socket '" + bench.socket().string() + "' >'" + out.string() + "' 2>&1";
  const int st = std::system(cmd.c_str());
  std::ifstream in(out);
  std::stringstream ss;
  ss << in.rdbuf();
  return {WIFEXITED(st) ? WEXITSTATUS(st) : -1, ss.str()};
}

}  // namespace

TEST_CASE("plan axes e2e: comp_raw judged on x, y and z, the plan fails the three-axis unit naming y, the same verdict everywhere") {
  require_sim();
  LiveBench bench(100.0, json::object(), true, nullptr, {"--axes", "3", "--axis-effect", "y=0.5*T1"});
  INFO("test dir " << bench.dir);
  LineClient c(bench.socket());
  REQUIRE(c.ok());
  REQUIRE(json::parse(*c.line(10s))["type"] == "hello");

  json s = c.call({{"cmd", "plan.start"}, {"text", kAxesPlan}, {"source", "axes.plan"}, {"units", {"SIM-0001"}}});
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

  // The limit judged on each axis, each measurement with its axis; y's not met, x's and z's met.
  json comp = json::object();
  for (const auto& m : unit["measurements"])
    if (m["measurement"] == "comp_raw") comp[m["axis"].get<std::string>()] = m;
  REQUIRE(comp.size() == 3);
  CHECK(comp["x"]["met"] == true);
  CHECK(comp["y"]["met"] == false);
  CHECK(comp["z"]["met"] == true);
  CHECK(comp["y"]["value"].get<double>() > 0.2);
  // The reason names y, and only y.
  REQUIRE(unit["reasons"].size() == 1);
  const std::string reason = unit["reasons"][0].get<std::string>();
  CHECK_THAT(reason, Catch::Contains("axis y: comp_raw = "));
  CHECK_THAT(reason, Catch::Contains("limit comp_raw < 0.2 (line 4)"));
  CHECK_THAT(reason, !Catch::Contains("axis x") && !Catch::Contains("axis z"));

  // The figures are the verifications' own (each axis' stored verification, not computed again).
  json got = c.call({{"cmd", "run.get"}, {"run_id", verify_run}});
  REQUIRE(code_of(got) == "ok");
  const json& vers = got["result"]["verifications"];
  REQUIRE(vers.size() == 3);
  for (const auto& v : vers) {
    const std::string axis = v["result"]["axis"].get<std::string>();
    INFO("axis " << axis);
    CHECK(comp[axis]["value"] == v["result"]["ratio"]);
  }

  // The unit's one verdict, the plan's: fail, the worst of its axes, each with its own model.
  json fit = c.call({{"cmd", "run.get"}, {"run_id", runs[0]["run_id"]}});
  REQUIRE(code_of(fit) == "ok");
  const json my = plan_axes_entry(fit["result"]["models"], "axis", "y");
  REQUIRE(my.is_object());
  REQUIRE(got["result"]["verdicts"].size() == 1);
  const json& rv = got["result"]["verdicts"][0];
  CHECK(rv["verdict"] == "fail");
  CHECK(rv["rule"] == "plan");
  REQUIRE(rv["axes"].size() == 3);
  CHECK(plan_axes_entry(rv["axes"], "axis", "x")["verdict"] == "pass");
  CHECK(plan_axes_entry(rv["axes"], "axis", "y")["verdict"] == "fail");
  CHECK(plan_axes_entry(rv["axes"], "axis", "z")["verdict"] == "pass");
  CHECK(plan_axes_entry(rv["axes"], "axis", "y")["model_id"] == my["id"]);
  CHECK(plan_axes_entry(rv["axes"], "axis", "y")["limits"].size() == 1);

  // The certificate carries it.
  json cert = c.call({{"cmd", "cert.get"}, {"serial", "SIM-0001"}});
  REQUIRE(code_of(cert) == "ok");
  CHECK(cert["result"]["certificate"]["verdict"] == "fail");
  CHECK(cert["result"]["certificate"]["qualification"]["verdict_id"] == rv["verdict_id"]);
  CHECK(plan_axes_entry(cert["result"]["certificate"]["qualification"]["axes"], "axis", "y")["verdict"] == "fail");
  // ... and each axis' current model and verdict for the page's axes table, signed with the rest.
  const json& cert_axes = cert["result"]["certificate"]["axes"];
  REQUIRE(cert_axes.size() == 3);
  CHECK(plan_axes_entry(cert_axes, "axis", "x")["verdict"] == "pass");
  CHECK(plan_axes_entry(cert_axes, "axis", "y")["verdict"] == "fail");
  CHECK(plan_axes_entry(cert_axes, "axis", "y")["model"]["id"] == my["id"]);
  CHECK(plan_axes_entry(cert_axes, "axis", "y")["decided_on_model"] == my["id"]);
  CHECK(plan_axes_entry(cert_axes, "axis", "y")["reasons"].size() == 1);
  CHECK(cert["result"]["certificate"].contains("signature"));
  // fogctl draws it as page 7, its axes table included, and the page checks against its signature.
  const auto [cert_code, cert_out] = plan_axes_fogctl(bench, "cert SIM-0001 -o c.html");
  INFO(cert_out);
  REQUIRE(cert_code == 0);
  std::ifstream page_in(bench.dir / "c.html");
  std::stringstream page;
  page << page_in.rdbuf();
  CHECK_THAT(page.str(), Catch::Contains("fogbench-certificate-page 7"));
  CHECK_THAT(page.str(), Catch::Contains("<td>y</td><td>fail</td>"));

  // fogctl shows the same: run get by axis, plan status with each measurement's axis.
  const auto [run_code, run_out] = plan_axes_fogctl(bench, "run get " + std::to_string(verify_run));
  INFO(run_out);
  CHECK(run_code == 0);
  CHECK_THAT(run_out, Catch::Contains("by axis: x PASS"));
  CHECK_THAT(run_out, Catch::Contains(" y FAIL "));
  const auto [plan_code, plan_out] = plan_axes_fogctl(bench, "plan status " + std::to_string(plan_id));
  INFO(plan_out);
  CHECK(plan_code == 0);
  CHECK_THAT(plan_out, Catch::Contains("comp_raw (y)"));
  CHECK_THAT(plan_out, Catch::Contains("axis y: comp_raw = "));
}
