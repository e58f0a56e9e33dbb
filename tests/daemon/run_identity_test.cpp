// A run's identity as the daemon records it (issue 13, point 1): the station id of the
// configuration, the operator from run.start or the socket's peer, fogbench's version and
// commit, the SHA-256 of the configuration and of the profile, each unit's power-on; shown by
// run.get. A bad operator name is refused naming the field, and no run is started.
#include "fixture.hpp"

#include "fogbench/daemon/handler.hpp"
#include "fogbench/daemon/run_identity.hpp"
#include "fogbench/model/sha256.hpp"
#include "fogbench/protocol/build_info.hpp"

using namespace fogbench;
using namespace fogbench::daemon;
using namespace fogbench::daemon::test;
using nlohmann::json;

namespace {
struct Rig {
  storage::Store store = memory_store();
  Station station{golden_config({{"station", {{"id", "bench-7"}}}}), store};
  Handler handler{station};
  SessionState session;
  json send(const json& req) { return handler.handle(req, session); }
};
}  // namespace

TEST_CASE("run identity: run.start records station, operator, software, hashes, run.get shows them") {
  Rig r;
  r.session.peer_user = "fogop";
  json start = r.send({{"id", 1}, {"cmd", "run.start"}, {"profile", "short"}, {"units", {"FOG-0001", "FOG-0002"}},
                       {"operator", "Grace Hopper"}});
  REQUIRE(start.contains("result"));
  const auto run_id = start["result"]["run_id"].get<std::int64_t>();
  json g = r.send({{"id", 2}, {"cmd", "run.get"}, {"run_id", run_id}});
  REQUIRE(g.contains("result"));
  const json& id = g["result"]["identity"];
  CHECK(id["station_id"] == "bench-7");
  CHECK(id["operator"] == "Grace Hopper");
  CHECK(id["operator_source"] == "client");
  CHECK(id["software_version"] == std::string(protocol::build_info().version));
  CHECK(id["git_hash"] == std::string(protocol::build_info().git_hash));
  // The hashes are of what the run stored: its config_json and its profile text, byte for byte.
  auto rec = r.store.get_run(run_id);
  REQUIRE(rec.has_value());
  CHECK(id["config_sha256"] == model::sha256_hex(rec->run.config_json));
  CHECK(id["profile_sha256"] == model::sha256_hex(rec->run.profile_text));
  CHECK(rec->run.config_json == r.station.config().source.dump());  // canonical: sorted keys, no spaces
  REQUIRE(id["units"].size() == 2);
  CHECK(id["units"][1]["serial"] == "FOG-0002");
}

TEST_CASE("run identity: without --operator the unix peer's user is recorded, on TCP nobody") {
  Rig r;
  r.session.peer_user = "fogop";
  json a = r.send({{"id", 1}, {"cmd", "run.start"}, {"profile", "short"}, {"units", {"FOG-0001"}}});
  REQUIRE(a.contains("result"));
  auto id = r.store.get_run_identity(a["result"]["run_id"].get<std::int64_t>());
  REQUIRE(id->has_value());
  CHECK((*id)->operator_name == "fogop");
  CHECK((*id)->operator_source == "peer");
  r.send({{"id", 2}, {"cmd", "run.abort"}});
  r.session.peer_user.clear();
  json b = r.send({{"id", 3}, {"cmd", "run.start"}, {"profile", "short"}, {"units", {"FOG-0001"}}});
  REQUIRE(b.contains("result"));
  id = r.store.get_run_identity(b["result"]["run_id"].get<std::int64_t>());
  CHECK((*id)->operator_name.empty());
  CHECK((*id)->operator_source == "none");
}

TEST_CASE("run identity: an operator with control characters, too long or not a string is bad_request naming `operator`, nothing started") {
  Rig r;
  for (const json& bad : {json("Ada\nLovelace"), json(std::string("x\x1b[31m")), json(std::string(65, 'a')), json(7), json("")}) {
    json reply = r.send({{"id", 1}, {"cmd", "run.start"}, {"profile", "short"}, {"units", {"FOG-0001"}}, {"operator", bad}});
    REQUIRE(reply.contains("error"));
    CHECK(reply["error"]["code"] == "bad_request");
    CHECK(reply["error"]["message"].get<std::string>().starts_with("operator:"));
  }
  CHECK(r.store.list_runs()->empty());
  CHECK_FALSE(r.station.active_run_id().has_value());
}

TEST_CASE("run identity: a unit's power-on seen by the daemon is recorded with the run") {
  Rig r;
  SyntheticBench bench(2);
  double clock_s = 0.0;
  const double wall0 = 1764057600.0;  // 2025-11-25T08:00:00Z
  // Both units silent for 5 s (read, no frames), then FOG-0001 starts up (its first frames say
  // so: warming_up, counter at 0) and sends for 10 s; FOG-0002 stays silent.
  for (int k = 0; k < 15; ++k) {
    TickInput in = bench.step(20.0, wall0 + clock_s);
    for (auto& u : in.units) u.frames = 0, u.gyro_dph.reset();
    if (k >= 5) in.units[0].frames = 100, in.units[0].gyro_dph = 0.0;
    if (k == 5) in.units[0].gyro_starts = 1;
    r.station.tick(clock_s, in);
    clock_s += 1.0;
  }
  json start = r.send({{"id", 1}, {"cmd", "run.start"}, {"profile", "short"}, {"units", {"FOG-0001", "FOG-0002"}}});
  REQUIRE(start.contains("result"));
  auto id = r.store.get_run_identity(start["result"]["run_id"].get<std::int64_t>());
  REQUIRE(id->has_value());
  const auto& u = (*id)->units;
  REQUIRE(u.size() == 2);
  // Dated to the start of the period its start-up frames came in (power_on.hpp): within a period.
  REQUIRE(u[0].since_power_on_s.has_value());
  CHECK(*u[0].since_power_on_s >= 9.0);
  CHECK(*u[0].since_power_on_s <= 11.0);
  REQUIRE(u[0].powered_on_at.has_value());
  CHECK(u[0].powered_on_at->starts_with("2025-11-25T08:00:0"));
  CHECK_FALSE(u[1].since_power_on_s.has_value());
  CHECK_FALSE(u[1].powered_on_at.has_value());
}

TEST_CASE("run identity: station.id must be a short printable string") {
  json j = golden_config_json();
  j["station"] = {{"id", 3}};
  CHECK(parse_daemon_config(j, golden_dir()).error().starts_with("station.id"));
  j["station"] = {{"id", "a\tb"}};
  CHECK(parse_daemon_config(j, golden_dir()).error().starts_with("station.id"));
  j["station"] = {{"name", "x"}};
  CHECK(parse_daemon_config(j, golden_dir()).error().starts_with("station.name"));
  j["station"] = {{"id", "line-2"}};
  CHECK(parse_daemon_config(j, golden_dir())->station_id == "line-2");
}
