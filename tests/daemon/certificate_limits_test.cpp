// A certificate states the limits in effect when each verdict was made (stored with the
// verification), not the configuration of the day it is printed; a verdict stored without them
// says "limits not recorded" (docs/cli.md, fogctl cert).
#include "fixture.hpp"

#include "fogbench/daemon/certificate.hpp"
#include "fogbench/daemon/handler.hpp"
#include "fogbench/storage/models.hpp"

using namespace fogbench;
using namespace fogbench::daemon;
using namespace fogbench::daemon::test;
using nlohmann::json;

namespace {
json analysis_limits(double noise_factor, double fail_s) {
  return {{"station", {{"id", "bench-7"}}},
          {"analysis", {{"verify_max_noise_factor", noise_factor}, {"verify_max_fail_s", fail_s}}}};
}
const json& check_named(const json& verdict, const std::string& name) {
  for (const auto& c : verdict["checks"])
    if (c["check"] == name) return c;
  FAIL("no check " << name << " in " << verdict.dump());
  static const json none;
  return none;
}
}  // namespace

TEST_CASE("certificate limits: the verdict's own limits after the configuration changed, the same hash, old verdicts say not recorded") {
  storage::Store store = memory_store();
  // The station's key, the same across the restart (in a daemon: its key file).
  const auto key = signing::SigningKey::generate();
  REQUIRE(key.has_value());
  json first;
  {
    Station station{golden_config(analysis_limits(2.5, 90.0)), store};
    station.set_signing_key(*key, {});
    Handler handler{station};
    SessionState session;
    SyntheticBench bench(1);
    double clock_s = 0.0;
    REQUIRE(handler.handle({{"id", 1}, {"cmd", "run.start"}, {"profile", "short"}, {"units", {"FOG-0001"}}}, session)
                .contains("result"));
    run_to_end(station, bench, clock_s);
    REQUIRE(handler.handle({{"id", 2}, {"cmd", "run.start"}, {"profile", "short"}, {"units", {"FOG-0001"}}, {"purpose", "verify"}},
                           session)
                .contains("result"));
    run_to_end(station, bench, clock_s);
    json r = handler.handle({{"id", 3}, {"cmd", "cert.get"}, {"serial", "FOG-0001"}}, session);
    REQUIRE(r.contains("result"));
    first = r["result"]["certificate"];
  }
  REQUIRE(first["verifications"].size() == 1);
  CHECK(check_named(first["verifications"][0], "compensated std / model noise std")["limit"] == 2.5);
  CHECK(check_named(first["verifications"][0], "longest failing interval, s")["limit"] == 90.0);

  // The station restarted with other limits: the certificate is the same, hash and limits.
  Station station{golden_config(analysis_limits(1.2, 30.0)), store};
  station.set_signing_key(*key, {});
  Handler handler{station};
  SessionState session;
  json r = handler.handle({{"id", 4}, {"cmd", "cert.get"}, {"serial", "FOG-0001"}}, session);
  REQUIRE(r.contains("result"));
  CHECK(r["result"]["issued_now"] == false);
  const json again = r["result"]["certificate"];
  CHECK(again["sha256"] == first["sha256"]);
  CHECK(check_named(again["verifications"][0], "compensated std / model noise std")["limit"] == 2.5);
  CHECK(check_named(again["verifications"][0], "longest failing interval, s")["limit"] == 90.0);
  // Built afresh under today's configuration: still the stored limits.
  auto body = certificate::build(store, station.config().analysis, "bench-7", "FOG-0001");
  REQUIRE(body);
  CHECK(check_named((*body)["verifications"][0], "longest failing interval, s")["limit"] == 90.0);

  // A verdict stored before the limits were (its result without them): not today's limits.
  auto vs = store.list_verifications(2);
  REQUIRE(vs);
  REQUIRE(vs->size() == 1);
  json old = json::parse(vs->front().result_json);
  REQUIRE(old.contains("max_noise_factor"));
  old.erase("max_noise_factor");
  old.erase("max_fail_s");
  REQUIRE(store.put_verification({2, 0, vs->front().model_id, old.dump(), vs->front().pass}));
  json third = handler.handle({{"id", 5}, {"cmd", "cert.get"}, {"serial", "FOG-0001"}}, session);
  REQUIRE(third.contains("result"));
  const json& verdicts = third["result"]["certificate"]["verifications"];
  REQUIRE(verdicts.size() == 2);
  for (const char* name : {"compensated std / model noise std", "longest failing interval, s"}) {
    INFO(name);
    CHECK(check_named(verdicts[0], name)["limit"].is_number());
    const json& c = check_named(verdicts[1], name);
    CHECK(c["limit"].is_null());
    CHECK(c["met"].is_null());
    CHECK(c["rule"].get<std::string>().find("limits not recorded") != std::string::npos);
  }
}
