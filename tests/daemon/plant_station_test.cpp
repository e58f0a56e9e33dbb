// The daemon's side of the plant store (issue 14): the `plant` configuration section, the units'
// lots at run.start, a completed run queued in the outbox once analysed, and `status`'s outbox.
#include "fixture.hpp"

#include "fogbench/daemon/handler.hpp"
#include "fogbench/storage/models.hpp"
#include "fogbench/storage/outbox.hpp"

using namespace fogbench;
using namespace fogbench::daemon;
using namespace fogbench::daemon::test;
using nlohmann::json;

namespace {
json plant_section() { return {{"plant", {{"conninfo", "host=/tmp password=secret"}, {"bench_id", "bench-7"}}}}; }
std::string refusal(json patch) {
  auto j = golden_config_json();
  j.merge_patch(patch);
  auto c = parse_daemon_config(j, golden_dir());
  REQUIRE_FALSE(c.has_value());
  return c.error();
}
}  // namespace

TEST_CASE("plant config: the section parses, its errors name the field, the connection string is not stored with runs") {
  auto none = parse_daemon_config(golden_config_json(), golden_dir());
  REQUIRE(none);
  CHECK_FALSE(none->plant.has_value());
  auto j = golden_config_json();
  j.merge_patch(plant_section());
  auto c = parse_daemon_config(j, golden_dir());
  REQUIRE(c);
  REQUIRE(c->plant.has_value());
  CHECK(c->plant->conninfo == "host=/tmp password=secret");
  CHECK(c->plant->bench_id == "bench-7");
  CHECK(c->plant->retry_max_s == 60);
  CHECK(c->plant->connect_timeout_s == 10);
  CHECK_FALSE(c->source["plant"].contains("conninfo"));
  CHECK(c->source.dump().find("secret") == std::string::npos);
  CHECK_THAT(refusal({{"plant", {{"bench_id", "b"}}}}), Catch::StartsWith("plant.conninfo"));
  CHECK_THAT(refusal({{"plant", {{"conninfo", "x"}}}}), Catch::StartsWith("plant.bench_id"));
  CHECK_THAT(refusal({{"plant", {{"conninfo", "x"}, {"bench_id", ""}}}}), Catch::StartsWith("plant.bench_id: empty"));
  CHECK_THAT(refusal({{"plant", {{"conninfo", "x"}, {"bench_id", "a\tb"}}}}),
             Catch::StartsWith("plant.bench_id: a control character at position 2"));
  CHECK_THAT(refusal({{"plant", {{"conninfo", "x"}, {"bench_id", "b"}, {"retry_max_s", -1}}}}),
             Catch::StartsWith("plant.retry_max_s"));
  for (const json& bad : {json(0), json(1.5), json(3601), json("10")})
    CHECK_THAT(refusal({{"plant", {{"conninfo", "x"}, {"bench_id", "b"}, {"connect_timeout_s", bad}}}}),
               Catch::StartsWith("plant.connect_timeout_s: expected a whole number of seconds, 1 to 3600"));
  CHECK_THAT(refusal({{"plant", {{"conninfo", "x"}, {"bench_id", "b"}, {"colour", 1}}}}),
             Catch::StartsWith("plant.colour: unknown field"));
}

TEST_CASE("plant lots: run.start stores each unit's lot, and a bad lot is refused with nothing stored") {
  auto store = memory_store();
  Station station{golden_config(), store};
  Handler handler{station};
  SessionState session;
  auto send = [&](const std::string& line) { return handler.handle_line(line, session); };
  auto code = [&](const std::string& line) {
    json r = send(line);
    return r.contains("error") ? r["error"]["code"].get<std::string>() + ": " + r["error"]["message"].get<std::string>()
                               : std::string("ok");
  };
  CHECK(code(R"({"id":1,"cmd":"run.start","profile":"short","units":["FOG-0001"],"lot":""})") ==
        "bad_request: lot: empty (expected 1..64 characters)");
  CHECK(code(R"({"id":1,"cmd":"run.start","profile":"short","units":["FOG-0001"],"lots":{"FOG-0009":"L"}})") ==
        "bad_request: lots.FOG-0009: not one of the run's units");
  CHECK(code(R"({"id":1,"cmd":"run.start","profile":"short","units":["FOG-0001"],"lots":{"FOG-0001":"a\nb"}})") ==
        "bad_request: lots.FOG-0001: a control character at position 2");
  CHECK(code(R"({"id":1,"cmd":"run.start","profile":"short","units":["FOG-0001"],"lot":"A","lots":{}})").starts_with(
      "bad_request: lot, lots"));
  CHECK(store.list_runs()->empty());
  REQUIRE(code(R"({"id":2,"cmd":"run.start","profile":"short","units":["FOG-0001","FOG-0002"],"lots":{"FOG-0002":"LOT \"7\" O'Neil"}})") == "ok");
  auto d = store.get_run(1);
  REQUIRE(d);
  CHECK_FALSE(d->run.units[0].lot.has_value());
  CHECK(d->run.units[1].lot == std::optional<std::string>("LOT \"7\" O'Neil"));
}

TEST_CASE("plant outbox: a completed run is queued once analysed, and status shows the depth, none without the section") {
  for (bool configured : {false, true}) {
    auto store = memory_store();
    Station st(golden_config(configured ? plant_section() : json::object()), store, 1.0,
               [] { return std::string("2026-01-01T00:00:00Z"); });
    SyntheticBench bench(2);
    double clock_s = 100.0;
    auto id = st.start_run("short", {"FOG-0001", "FOG-0002"}, storage::Purpose::fit, {{"cmd", "run.start"}, {"lot", "L-1"}});
    REQUIRE(id);
    run_to_end(st, bench, clock_s);
    REQUIRE(store.get_run(*id)->run.state == storage::RunState::completed);
    REQUIRE(store.list_models("FOG-0001")->size() == 1);  // the analysis ran before the queuing
    const json s = st.status();
    INFO("configured " << configured);
    if (!configured) {
      CHECK_FALSE(s.contains("plant"));
      CHECK(store.outbox_status()->depth == 0);
      continue;
    }
    REQUIRE(s.contains("plant"));
    CHECK(s["plant"]["bench_id"] == "bench-7");
    CHECK(s["plant"]["outbox_depth"] == 1);
    CHECK(s["plant"]["last_error"].is_null());
    auto head = store.pending_replications(10);
    REQUIRE(head->size() == 1);
    CHECK(head->front().run_id == *id);
    REQUIRE(store.mark_replication_failed(head->front().id, "connect to the plant store: refused"));
    CHECK(st.status()["plant"]["last_error"] == "connect to the plant store: refused");
    CHECK(st.status()["plant"]["attempts"] == 1);
    REQUIRE(store.mark_replicated(head->front().id));
    CHECK(st.status()["plant"]["outbox_depth"] == 0);
    CHECK(st.status()["plant"]["sent"] == 1);
  }
}
