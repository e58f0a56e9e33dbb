// The command handler without a socket: hello, replies, and every error code of the protocol.
#include "fixture.hpp"

#include "fogbench/protocol/framing.hpp"
#include "fogbench/daemon/handler.hpp"
#include "fogbench/storage/models.hpp"

using namespace fogbench;
using namespace fogbench::daemon;
using namespace fogbench::protocol;
using namespace fogbench::daemon::test;
using nlohmann::json;

namespace {
struct Rig {
  storage::Store store = memory_store();
  Station station{golden_config(), store};
  Handler handler{station};
  SessionState session;
  json send(const std::string& line) { return handler.handle_line(line, session); }
  std::string code(const std::string& line) {
    json r = send(line);
    REQUIRE(r["type"] == "reply");
    if (!r.contains("error")) return "ok";
    CHECK(r["error"]["message"].is_string());
    return r["error"]["code"];
  }
};
}  // namespace

TEST_CASE("handler: hello names the protocol") {
  json h = Handler::hello();
  CHECK(h["type"] == "hello");
  CHECK(h["protocol"] == 1);
  CHECK(h["max_line_bytes"] == kMaxLineBytes);
  CHECK(h["limits"]["max_line_bytes"] == kMaxLineBytes);
  CHECK(h["limits"]["max_depth"] == kMaxDepth);
}

TEST_CASE("handler: a reply carries the request's id, number or string") {
  Rig r;
  json a = r.send(R"({"id":41,"cmd":"status"})");
  CHECK(a["id"] == 41);
  CHECK(a["type"] == "reply");
  CHECK(a["result"]["run"].is_null());
  CHECK(a["result"]["units"].size() == 2);
  json b = r.send(R"({"id":"abc","cmd":"run.list"})");
  CHECK(b["id"] == "abc");
  CHECK(b["result"]["runs"].empty());
}

TEST_CASE("handler: error codes of malformed requests") {
  Rig r;
  CHECK(r.code("{not json") == "bad_json");
  CHECK(r.code("") == "bad_json");
  CHECK(r.code("[1,2]") == "bad_request");
  CHECK(r.code(R"({"cmd":"status"})") == "bad_request");           // no id
  CHECK(r.code(R"({"id":[1],"cmd":"status"})") == "bad_request");  // id of the wrong type
  CHECK(r.code(R"({"id":1})") == "bad_request");                   // no cmd
  CHECK(r.code(R"({"id":1,"cmd":7})") == "bad_request");
  CHECK(r.code(R"({"id":1,"cmd":"launch"})") == "unknown_command");
  CHECK(r.send("{not json")["id"].is_null());
  CHECK(r.send(R"({"id":9,"cmd":"launch"})")["id"] == 9);
}

TEST_CASE("handler: error codes of run commands, and refusals that store nothing") {
  Rig r;
  CHECK(r.code(R"({"id":1,"cmd":"run.start","units":["FOG-0001"]})") == "bad_request");  // no profile
  CHECK(r.code(R"({"id":1,"cmd":"run.start","profile":"short"})") == "bad_request");     // no units
  CHECK(r.code(R"({"id":1,"cmd":"run.start","profile":"short","units":"FOG-0001"})") == "bad_request");
  CHECK(r.code(R"({"id":1,"cmd":"run.start","profile":"short","units":[1]})") == "bad_request");
  CHECK(r.code(R"({"id":1,"cmd":"run.start","profile":3,"units":["FOG-0001"]})") == "bad_request");
  CHECK(r.code(R"({"id":1,"cmd":"run.start","profile":"short","units":["FOG-0001"],"purpose":"x"})") == "bad_request");
  CHECK(r.code(R"({"id":1,"cmd":"run.start","profile":"short","units":["FOG-0001"],"purpose":"verify"})") == "unknown_serial");
  CHECK(r.code(R"({"id":1,"cmd":"run.start","profile":"short","units":["FOG-7"]})") == "unknown_serial");
  CHECK(r.code(R"({"id":1,"cmd":"run.start","profile":"hot","units":["FOG-0001"]})") == "limits");
  CHECK(r.code(R"({"id":1,"cmd":"run.start","profile":"broken","units":["FOG-0001"]})") == "invalid_profile");
  CHECK(r.code(R"({"id":1,"cmd":"run.start","profile":"gone","units":["FOG-0001"]})") == "not_found");
  CHECK(r.code(R"({"id":1,"cmd":"run.abort"})") == "not_found");
  CHECK(r.store.list_runs()->empty());

  CHECK(r.code(R"({"id":2,"cmd":"run.start","profile":"short","units":["FOG-0001"]})") == "ok");
  CHECK(r.code(R"({"id":3,"cmd":"run.start","profile":"short","units":["FOG-0002"]})") == "busy");
  CHECK(r.code(R"({"id":4,"cmd":"model.fit","run_id":1})") == "busy");  // still running
  CHECK(r.code(R"({"id":5,"cmd":"run.abort","run_id":99})") == "not_found");
  CHECK(r.code(R"({"id":6,"cmd":"run.abort","reason":"test"})") == "ok");
  CHECK(r.store.get_run(1)->run.state_reason == "aborted by operator: test");
}

TEST_CASE("handler: error codes of queries") {
  Rig r;
  CHECK(r.code(R"({"id":1,"cmd":"run.get"})") == "bad_request");
  CHECK(r.code(R"({"id":1,"cmd":"run.get","run_id":"1"})") == "bad_request");
  CHECK(r.code(R"({"id":1,"cmd":"run.get","run_id":0})") == "bad_request");
  CHECK(r.code(R"({"id":1,"cmd":"run.get","run_id":5})") == "not_found");
  CHECK(r.code(R"({"id":1,"cmd":"run.samples","run_id":5})") == "not_found");
  CHECK(r.code(R"({"id":1,"cmd":"run.samples","run_id":1,"limit":0})") == "bad_request");
  CHECK(r.code(R"({"id":1,"cmd":"run.list","state":"sleeping"})") == "bad_request");
  CHECK(r.code(R"({"id":1,"cmd":"run.list","limit":"ten"})") == "bad_request");
  CHECK(r.code(R"({"id":1,"cmd":"model.get"})") == "bad_request");
  CHECK(r.code(R"({"id":1,"cmd":"model.get","serial":"FOG-0001"})") == "not_found");
  CHECK(r.code(R"({"id":1,"cmd":"model.get","model_id":3})") == "not_found");
  CHECK(r.code(R"({"id":1,"cmd":"model.fit"})") == "bad_request");
  CHECK(r.code(R"({"id":1,"cmd":"model.fit","run_id":4})") == "not_found");
  CHECK(r.code(R"({"id":1,"cmd":"model.verify","run_id":4})") == "not_found");
  CHECK(r.code(R"({"id":1,"cmd":"profile.validate"})") == "bad_request");
  CHECK(r.code(R"({"id":1,"cmd":"profile.validate","name":"hot"})") == "limits");
  CHECK(r.code(R"({"id":1,"cmd":"profile.validate","text":"setpoint 20 C\nhold 1 min\n"})") == "ok");
  CHECK(r.code(R"({"id":1,"cmd":"profile.validate","text":"hold\n"})") == "invalid_profile");
  // Rate steps without a configured rate table: refused by line and column, not run as
  // temperatures alone.
  const json rate = r.send(R"({"id":1,"cmd":"profile.validate","text":"setpoint 20 C\nhold 5 min\nrate 100 dps for 60 s\n"})");
  INFO(rate.dump());
  CHECK(r.code(R"({"id":1,"cmd":"profile.validate","text":"setpoint 20 C\nhold 5 min\nrate 100 dps for 60 s\n"})") == "invalid_profile");
  CHECK(rate.dump().find("<text>:3:") != std::string::npos);
  CHECK(rate.dump().find("no rate table is configured") != std::string::npos);
}

TEST_CASE("handler: a profile with rate steps is accepted once a rate table is configured, within its limit") {
  storage::Store store = memory_store();
  // 100 deg/s needs a coarser scale than the golden units' (fixture.hpp).
  Station station{golden_config({{"drivers", golden_units_at_scale(1e-3)},
                                 {"rate_table", {{"kind", "acutrol"}, {"link", {{"transport", "tcp"}, {"host", "127.0.0.1"}, {"port", 9888}}},
                                                 {"max_rate_dps", 200}}}}),
                  store};
  Handler handler{station};
  SessionState session;
  auto send = [&](const std::string& line) { return handler.handle_line(line, session); };
  const json ok = send(R"({"id":1,"cmd":"profile.validate","text":"setpoint 20 C\nhold 5 min\nrate 100 dps for 60 s\n"})");
  INFO(ok.dump());
  CHECK_FALSE(ok.contains("error"));
  const json over = send(R"({"id":2,"cmd":"profile.validate","text":"setpoint 20 C\nhold 5 min\nrate 300 dps for 60 s\n"})");
  INFO(over.dump());
  REQUIRE(over.contains("error"));
  CHECK(over["error"]["code"] == "limits");
  CHECK(over.dump().find("rate_table.max_rate_dps") != std::string::npos);
}

TEST_CASE("handler: samples page through a stored run, by unit index or serial") {
  Rig r;
  SyntheticBench bench(2);
  REQUIRE(r.code(R"({"id":1,"cmd":"run.start","profile":"short","units":["FOG-0001","FOG-0002"]})") == "ok");
  for (int i = 0; i < 30; ++i) r.station.tick(i, bench.step(20));
  json page = r.send(R"({"id":2,"cmd":"run.samples","run_id":1,"unit":"FOG-0002","offset":10,"limit":5})");
  REQUIRE(page.contains("result"));
  CHECK(page["result"]["unit"] == 1);
  CHECK(page["result"]["total"] == 30);
  REQUIRE(page["result"]["samples"].size() == 5);
  CHECK(page["result"]["samples"][0]["t_s"] == 10.0);
  CHECK(page["result"]["samples"][0]["phase"] == "hold");
  CHECK(r.code(R"({"id":3,"cmd":"run.samples","run_id":1,"unit":2})") == "not_found");
  CHECK(r.code(R"({"id":3,"cmd":"run.samples","run_id":1,"unit":"FOG-0009"})") == "not_found");
  CHECK(r.code(R"({"id":3,"cmd":"run.samples","run_id":1,"unit":true})") == "bad_request");
}

TEST_CASE("handler: subscribe marks the session") {
  Rig r;
  CHECK(!r.session.subscribed);
  CHECK(r.code(R"({"id":1,"cmd":"subscribe"})") == "ok");
  CHECK(r.session.subscribed);
}

TEST_CASE("handler: deeply nested or huge input is an error reply, not a crash") {
  Rig r;
  CHECK(r.code(std::string(100000, '[')) == "bad_json");
  CHECK(r.code(R"({"id":1,"cmd":"run.list","limit":1e308})") == "bad_request");
  CHECK(r.code(R"({"id":1,"cmd":"run.get","run_id":-1})") == "bad_request");
  CHECK(Handler::too_long()["error"]["code"] == "bad_request");
  // Issue 11's crash line: 100,000 levels inside a valid request, under the line limit.
  json deep = r.send(R"({"id":1,"cmd":"status","x":)" + std::string(100000, '[') + std::string(100000, ']') + "}");
  CHECK(deep["error"]["code"] == "bad_json");
  CHECK(deep["error"]["message"] == "nesting deeper than 64 levels at column 91");  // 27 + 64
}

TEST_CASE("handler: a key twice in a request is bad_json, and nothing runs") {
  Rig r;
  // Before: the last "cmd" won and this aborted the run.
  json a = r.send(R"({"id":1,"cmd":"status","cmd":"run.abort"})");
  CHECK(a["error"]["code"] == "bad_json");
  CHECK(a["error"]["message"] == R"(duplicate key "cmd")");
  CHECK(r.code(R"({"id":1,"id":2,"cmd":"status"})") == "bad_json");
  CHECK(r.code(R"({"id":1,"cmd":"run.start","profile":"short","units":["FOG-0001"],"x":{"a":1,"a":1}})") == "bad_json");
  CHECK(r.station.active_run_id() == std::nullopt);
}

TEST_CASE("handler: a read-only connection (TCP) may query but not change anything") {
  Rig r;
  r.session.may_control = false;
  CHECK(r.code(R"({"id":1,"cmd":"status"})") == "ok");
  CHECK(r.code(R"({"id":2,"cmd":"run.list"})") == "ok");
  CHECK(r.code(R"({"id":3,"cmd":"subscribe"})") == "ok");
  CHECK(r.code(R"({"id":4,"cmd":"run.start","profile":"short","units":["FOG-0001"]})") == "forbidden");
  CHECK(r.code(R"({"id":5,"cmd":"run.abort"})") == "forbidden");
  CHECK(r.code(R"({"id":6,"cmd":"model.fit","run_id":1})") == "forbidden");
  CHECK(r.code(R"({"id":7,"cmd":"model.verify","run_id":1})") == "forbidden");
  CHECK(r.store.list_runs()->empty());
}

TEST_CASE("handler: with a control token, a read-only connection controls only with a valid `token` field") {
  Rig r;
  r.session.may_control = false;
  r.session.control_token = "0123456789abcdef-secret";
  CHECK(r.code(R"({"id":1,"cmd":"status"})") == "ok");
  CHECK(r.code(R"({"id":2,"cmd":"run.start","profile":"short","units":["FOG-0001"]})") == "forbidden");
  CHECK(r.code(R"({"id":3,"cmd":"run.start","profile":"short","units":["FOG-0001"],"token":"wrong"})") == "forbidden");
  // A prefix of the token, and the token with a byte more, are not the token.
  CHECK(r.code(R"({"id":4,"cmd":"run.abort","token":"0123456789abcdef"})") == "forbidden");
  CHECK(r.code(R"({"id":5,"cmd":"run.abort","token":"0123456789abcdef-secretX"})") == "forbidden");
  CHECK(r.code(R"({"id":6,"cmd":"run.start","profile":"short","units":["FOG-0001"],"token":7})") == "bad_request");
  CHECK(r.store.list_runs()->empty());
  CHECK(r.code(R"({"id":7,"cmd":"run.start","profile":"short","units":["FOG-0001"],"token":"0123456789abcdef-secret"})") == "ok");
  // The command is audited as received, without the credential.
  auto d = r.store.get_run(1);
  REQUIRE(d.has_value());
  for (const auto& e : d->events) CHECK(e.detail_json.find("secret") == std::string::npos);
  CHECK(r.code(R"({"id":8,"cmd":"run.abort","token":"0123456789abcdef-secret"})") == "ok");
  // Reading needs no token, and a token does not hurt.
  CHECK(r.code(R"({"id":9,"cmd":"run.list","token":"0123456789abcdef-secret"})") == "ok");
}

TEST_CASE("handler: run.resume takes up only an interrupted run, and is a control command") {
  Rig r;
  CHECK(r.code(R"({"id":1,"cmd":"run.resume"})") == "bad_request");
  CHECK(r.code(R"({"id":2,"cmd":"run.resume","run_id":"1"})") == "bad_request");
  CHECK(r.code(R"({"id":3,"cmd":"run.resume","run_id":1})") == "not_found");
  REQUIRE(r.code(R"({"id":4,"cmd":"run.start","profile":"short","units":["FOG-0001"]})") == "ok");
  CHECK(r.code(R"({"id":5,"cmd":"run.resume","run_id":1})") == "busy");
  REQUIRE(r.code(R"({"id":6,"cmd":"run.abort"})") == "ok");
  json aborted = r.send(R"({"id":7,"cmd":"run.resume","run_id":1})");
  CHECK(aborted["error"]["code"] == "bad_request");
  CHECK_THAT(aborted["error"]["message"].get<std::string>(), Catch::Contains("only an interrupted run resumes"));
  r.session.may_control = false;
  CHECK(r.code(R"({"id":8,"cmd":"run.resume","run_id":1})") == "forbidden");
}

TEST_CASE("handler: the workbench on stored runs: model.compare, model.diagnose, model.add_term") {
  Rig r;
  SyntheticBench bench(1);
  double clock_s = 0.0;
  // Run 1 fits FOG-0001's model 1 when it completes; run 2 is a second run of the same gyro.
  REQUIRE(r.code(R"({"id":1,"cmd":"run.start","profile":"short","units":["FOG-0001"],"purpose":"fit"})") == "ok");
  run_to_end(r.station, bench, clock_s);
  REQUIRE(r.code(R"({"id":2,"cmd":"run.start","profile":"short","units":["FOG-0001"],"purpose":"verify"})") == "ok");
  run_to_end(r.station, bench, clock_s);
  REQUIRE(r.store.current_model("FOG-0001")->has_value());

  json c = r.send(R"({"id":3,"cmd":"model.compare","run_id":2,"unit":"FOG-0001"})");
  REQUIRE(c.contains("result"));
  CHECK(c["result"]["model_id"] == 1);
  CHECK(c["result"]["result"].contains("adequate"));

  json d = r.send(R"({"id":4,"cmd":"model.diagnose","run_id":1,"unit":0,"held_out":[2]})");
  REQUIRE(d.contains("result"));
  CHECK(d["result"]["held_out"] == json::array({2}));
  CHECK(d["result"]["result"]["candidates"].is_array());
  CHECK(d["result"]["result"]["adequate"].is_boolean());

  json a = r.send(R"({"id":5,"cmd":"model.add_term","run_id":1,"unit":0,"term":"T1"})");
  REQUIRE(a.contains("result"));
  CHECK(a["result"]["parent_id"] == 1);
  CHECK(a["result"]["version"] == 2);
  CHECK(a["result"]["model"]["parent"]["method"].is_string());  // the lineage travels with the model
  CHECK((*r.store.current_model("FOG-0001"))->id == a["result"]["model_id"].get<std::int64_t>());

  // Bad input: a clear error, nothing stored.
  CHECK(r.code(R"({"id":6,"cmd":"model.add_term","run_id":1,"unit":0,"term":"T9"})") == "bad_request");
  CHECK(r.code(R"({"id":7,"cmd":"model.add_term","run_id":1,"unit":0})") == "bad_request");
  CHECK(r.code(R"({"id":8,"cmd":"model.diagnose","run_id":1,"held_out":"2"})") == "bad_request");
  CHECK(r.code(R"({"id":9,"cmd":"model.diagnose","run_id":1,"held_out":[7]})") == "not_found");
  // Held out means not fitted on, and each run once: the diagnosed run itself or a run twice
  // would make the held-out figures lie; a list without bound would hold the analysis worker.
  json self = r.send(R"({"id":9,"cmd":"model.diagnose","run_id":1,"held_out":[2,1]})");
  CHECK(self["error"]["code"] == "bad_request");
  CHECK(self["error"]["message"] == "held_out[1]: run 1 is the run diagnosed, not a held-out one");
  json twice = r.send(R"({"id":9,"cmd":"model.diagnose","run_id":1,"held_out":[2,2]})");
  CHECK(twice["error"]["message"] == "held_out[1]: run 2 is listed twice");
  json many = json::parse(R"({"id":9,"cmd":"model.diagnose","run_id":1})");
  for (int i = 2; i <= 34; ++i) many["held_out"].push_back(i);
  json too_many = r.send(many.dump());
  CHECK(too_many["error"]["code"] == "bad_request");
  CHECK(too_many["error"]["message"] == "held_out: at most 32 runs, got 33");
  CHECK(r.code(R"({"id":10,"cmd":"model.compare","run_id":1,"model_id":99})") == "not_found");
  CHECK(r.store.list_models("FOG-0001")->size() == 2);
  // add_term stores a model: a control command; compare and diagnose only read.
  r.session.may_control = false;
  CHECK(r.code(R"({"id":11,"cmd":"model.add_term","run_id":1,"term":"T1"})") == "forbidden");
  CHECK(r.code(R"({"id":12,"cmd":"model.compare","run_id":2})") == "ok");
  // A run being recorded is no held-out run yet.
  r.session.may_control = true;
  REQUIRE(r.code(R"({"id":13,"cmd":"run.start","profile":"short","units":["FOG-0001"],"purpose":"verify"})") == "ok");
  json active = r.send(R"({"id":14,"cmd":"model.diagnose","run_id":1,"held_out":[2,3]})");
  CHECK(active["error"]["code"] == "busy");
  CHECK(active["error"]["message"] == "held_out[1]: run 3 is still active");
}

TEST_CASE("handler: run.start's purpose is fit or verify, anything else is bad_request naming the field") {
  Rig r;
  json j = r.send(R"({"id":1,"cmd":"run.start","profile":"short","units":["FOG-0001"],"purpose":"calibrate"})");
  CHECK(j["error"]["code"] == "bad_request");
  CHECK_THAT(j["error"]["message"].get<std::string>(), Catch::Contains("purpose"));
  CHECK(r.store.list_runs()->empty());
}

TEST_CASE("handler: a fit that fails on the run's data has one code, whichever command meets it") {
  Rig r;
  SyntheticBench bench(1);
  double clock_s = 0.0;
  REQUIRE(r.code(R"({"id":1,"cmd":"run.start","profile":"short","units":["FOG-0001"]})") == "ok");
  run_to_end(r.station, bench, clock_s);  // run 1 completes: model 1
  REQUIRE(r.store.current_model("FOG-0001")->has_value());
  // Run 2 lasts 20 s, far too short to fit anything on.
  REQUIRE(r.code(R"({"id":2,"cmd":"run.start","profile":"short","units":["FOG-0001"]})") == "ok");
  run_to_end(r.station, bench, clock_s, 20);
  REQUIRE(r.code(R"({"id":3,"cmd":"run.abort"})") == "ok");
  const json fit = r.send(R"({"id":4,"cmd":"model.fit","run_id":2})");
  const json add = r.send(R"({"id":5,"cmd":"model.add_term","run_id":2,"term":"T1"})");
  REQUIRE(fit.contains("error"));
  REQUIRE(add.contains("error"));
  // Before, model.fit said internal and model.add_term bad_request for the same failure.
  CHECK(fit["error"]["code"] == "internal");
  CHECK(add["error"]["code"] == fit["error"]["code"]);
  CHECK_THAT(fit["error"]["message"].get<std::string>(), Catch::Contains("fit failed ("));
  CHECK(r.store.list_models("FOG-0001")->size() == 1);  // nothing stored
}

TEST_CASE("handler: names and reasons with control characters or beyond their bound are refused, naming the field") {
  Rig r;
  auto message = [&](const std::string& line) {
    json rep = r.send(line);
    REQUIRE(rep.contains("error"));
    CHECK(rep["error"]["code"] == "bad_request");
    return rep["error"]["message"].get<std::string>();
  };
  CHECK(message(R"({"id":1,"cmd":"run.start","profile":"short","units":["FOG-0001","FOG\u001b[2J"]})") ==
        "units[1]: control character 0x1B at byte 4");
  CHECK(message(R"({"id":1,"cmd":"run.start","profile":"sh\u0007ort","units":["FOG-0001"]})") ==
        "profile: control character 0x07 at byte 3");
  CHECK(message(json{{"id", 1}, {"cmd", "run.start"}, {"profile", "short"}, {"units", {std::string(65, 'F')}}}.dump())
            .starts_with("units[0]: longer than 64 bytes"));
  CHECK(r.store.list_runs()->empty());

  REQUIRE(r.code(R"({"id":2,"cmd":"run.start","profile":"short","units":["FOG-0001"]})") == "ok");
  CHECK(message(R"({"id":3,"cmd":"run.abort","reason":"done\r\nroot# "})") == "reason: control character 0x0D at byte 5");
  CHECK(r.store.get_run(1)->run.state != storage::RunState::aborted);  // the refusal touched nothing
}
