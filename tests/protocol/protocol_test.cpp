// The protocol's codes, hello and message shapes: what the daemon writes is what fogctl reads.
#include <catch2/catch.hpp>

#include <cmath>

#include "fogbench/protocol/framing.hpp"
#include "fogbench/protocol/protocol.hpp"

using namespace fogbench::protocol;
using nlohmann::json;

TEST_CASE("protocol: every error code has its documented wire string, and back") {
  // docs/protocol.md's table, in its order.
  const std::pair<ErrorCode, const char*> table[] = {
      {ErrorCode::bad_json, "bad_json"},         {ErrorCode::bad_request, "bad_request"},
      {ErrorCode::unknown_command, "unknown_command"}, {ErrorCode::not_found, "not_found"},
      {ErrorCode::busy, "busy"},                 {ErrorCode::invalid_profile, "invalid_profile"},
      {ErrorCode::limits, "limits"},             {ErrorCode::unknown_serial, "unknown_serial"},
      {ErrorCode::forbidden, "forbidden"},       {ErrorCode::internal, "internal"},
      {ErrorCode::unavailable, "unavailable"},   {ErrorCode::invalid_config, "invalid_config"},
  };
  for (const auto& [code, text] : table) {
    CHECK(to_string(code) == text);
    CHECK(error_code_from_string(text) == code);
  }
  CHECK_FALSE(error_code_from_string("connection").has_value());
}

TEST_CASE("protocol: hello carries the version and the limits, and a client takes only its own version") {
  const json h = to_json(Hello{"1.2.3"});
  CHECK(h["type"] == "hello");
  CHECK(h["protocol"] == kProtocolVersion);
  CHECK(h["max_line_bytes"] == kMaxLineBytes);
  CHECK(h["limits"]["max_depth"] == kMaxDepth);
  auto back = hello_from_json(h);
  REQUIRE(back.has_value());
  CHECK(back->version == "1.2.3");

  json other = h;
  other["protocol"] = kProtocolVersion + 1;
  auto refused = hello_from_json(other);
  REQUIRE_FALSE(refused.has_value());
  CHECK_THAT(refused.error(), Catch::Contains("speaks protocol " + std::to_string(kProtocolVersion + 1)));

  json none = h;
  none.erase("protocol");
  CHECK_THAT(hello_from_json(none).error(), Catch::Contains("no protocol version"));
  CHECK_THAT(hello_from_json(json{{"type", "reply"}}).error(), Catch::Contains("did not say hello"));
}

TEST_CASE("protocol: a stored sample goes to JSON and back, values not read as null") {
  Sample s;
  s.t_s = 598.0;
  s.wall_time = 1795298101.25;
  s.setpoint_c = 20.0;
  s.chamber_c = std::nan("");  // not read: null on the wire, absent when read back
  s.gyro_dph = -7.98;
  s.frames = 100;
  s.t1_c = 20.5;
  s.phase = "hold";
  s.step = 1;
  s.flags = 1;
  const json j = to_json(s);
  CHECK(j["chamber_c"].is_null());
  CHECK(j["t2_c"].is_null());
  CHECK(j["since_power_on_s"].is_null());
  CHECK(j.contains("compensated_dph"));
  CHECK(j["compensated_dph"].is_null());  // no live compensation: null, present
  auto back = sample_from_json(json::parse(j.dump()));
  REQUIRE(back.has_value());
  CHECK(back->t_s == 598.0);
  CHECK(back->wall_time == 1795298101.25);
  CHECK_FALSE(back->chamber_c.has_value());
  CHECK(back->gyro_dph == -7.98);
  CHECK(back->frames == 100);
  CHECK(back->phase == "hold");
  CHECK(back->step == 1);
  CHECK(back->flags == 1);
  CHECK_FALSE(back->compensated_dph.has_value());
  s.compensated_dph = 0.0125;
  auto comp = sample_from_json(json::parse(to_json(s).dump()));
  REQUIRE(comp.has_value());
  CHECK(comp->compensated_dph == 0.0125);
  // A row from a daemon before the field: read as none.
  json old = to_json(s);
  old.erase("compensated_dph");
  CHECK_FALSE(sample_from_json(old)->compensated_dph.has_value());
  old["compensated_dph"] = "low";
  CHECK(sample_from_json(old).error() == "sample.compensated_dph: expected a number or null");
}

TEST_CASE("protocol: a malformed sample is refused naming the field") {
  json j = to_json(Sample{});
  j["gyro_dph"] = "fast";
  CHECK(sample_from_json(j).error() == "sample.gyro_dph: expected a number or null");
  j = to_json(Sample{});
  j.erase("t_s");
  CHECK(sample_from_json(j).error() == "sample.t_s: expected a number");
}

TEST_CASE("protocol: pushed sample and event messages go to JSON and back") {
  SampleMessage m;
  m.run_id = 3;
  m.t_s = 660.0;
  m.state = "running";
  m.phase = "heating";
  m.step = 2;
  m.elapsed_s = 660.0;
  m.remaining_s = 1140.0;
  m.setpoint_c = 21.0;
  m.unit = 1;
  m.serial = "FOG-0002";
  m.gyro_dph = -8.11;
  m.frames = 100;
  m.compensated_dph = 0.021;
  const json j = to_json(m);
  CHECK(j["compensated_dph"] == 0.021);  // the web panel reads this name
  CHECK(j["type"] == "sample");
  CHECK(j["chamber_c"].is_null());
  auto back = sample_message_from_json(json::parse(j.dump()));
  REQUIRE(back.has_value());
  CHECK(back->serial == "FOG-0002");
  CHECK(back->step == 2);
  CHECK(back->gyro_dph == -8.11);
  CHECK(back->compensated_dph == 0.021);
  CHECK_FALSE(back->chamber_c.has_value());
  // No rate table: no rate_in_dps field at all; with one, the commanded rate there and back.
  CHECK_FALSE(j.contains("rate_in_dps"));
  CHECK_FALSE(back->rate_in_dps.has_value());
  m.rate_in_dps = -10.0;
  const json jt = to_json(m);
  CHECK(jt["rate_in_dps"] == -10.0);
  auto back_t = sample_message_from_json(json::parse(jt.dump()));
  REQUIRE(back_t.has_value());
  CHECK(back_t->rate_in_dps == -10.0);

  const json e = to_json(EventMessage{3, std::nullopt, "state", {{"to", "aborted"}}});
  CHECK(e["t_s"].is_null());
  auto eb = event_message_from_json(e);
  REQUIRE(eb.has_value());
  CHECK(eb->kind == "state");
  CHECK(eb->detail["to"] == "aborted");
  CHECK_THAT(event_message_from_json(j).error(), Catch::Contains("type \"event\""));
}

TEST_CASE("framing: a line far over the limit arriving in many small reads is reported once it passes") {
  // The splitter resumes its newline search where it stopped: feeding 64 KiB at a time up to the
  // limit never reports a line, and one byte more is too_long.
  LineSplitter s(1 << 20);
  std::string line;
  const std::string chunk(1 << 16, 'x');
  for (int i = 0; i < 16; ++i) {
    s.feed(chunk);
    REQUIRE(s.next(line) == LineSplitter::Status::incomplete);
  }
  s.feed("y");
  CHECK(s.next(line) == LineSplitter::Status::too_long);
}

TEST_CASE("framing: a newline in a later read ends a line whose start was scanned already") {
  LineSplitter s;
  std::string line;
  s.feed("{\"id\":");
  REQUIRE(s.next(line) == LineSplitter::Status::incomplete);
  s.feed("1}");
  REQUIRE(s.next(line) == LineSplitter::Status::incomplete);
  s.feed("\n{\"id\":2}\n");
  REQUIRE(s.next(line) == LineSplitter::Status::line);
  CHECK(line == "{\"id\":1}");
  REQUIRE(s.next(line) == LineSplitter::Status::line);
  CHECK(line == "{\"id\":2}");
}

TEST_CASE("protocol: a three-axis unit's y and z are fields of its samples only, null where not read") {
  Sample s;
  s.t_s = 5.0;
  s.gyro_dph = 1.5;
  CHECK_FALSE(to_json(s).contains("gyro_y_dph"));  // a one-axis unit's sample as before
  CHECK_FALSE(sample_from_json(to_json(s))->three_axis);
  s.three_axis = true;
  s.gyro_y_dph = 101.25;  // z not read this second
  const json j = to_json(s);
  CHECK(j["gyro_y_dph"] == 101.25);
  CHECK(j["gyro_z_dph"].is_null());
  auto back = sample_from_json(json::parse(j.dump()));
  REQUIRE(back.has_value());
  CHECK(back->three_axis);
  CHECK(back->gyro_y_dph == 101.25);
  CHECK_FALSE(back->gyro_z_dph.has_value());
  json bad = j;
  bad["gyro_z_dph"] = "x";
  auto refused = sample_from_json(bad);
  REQUIRE_FALSE(refused.has_value());
  CHECK(refused.error().find("gyro_z_dph") != std::string::npos);

  SampleMessage m;
  m.state = "running";
  m.phase = "hold";
  m.serial = "FOG-0001";
  CHECK_FALSE(to_json(m).contains("gyro_z_dph"));
  m.three_axis = true;
  m.gyro_y_dph = -2.0;
  m.gyro_z_dph = 3.0;
  auto mb = sample_message_from_json(json::parse(to_json(m).dump()));
  REQUIRE(mb.has_value());
  CHECK(mb->three_axis);
  CHECK(mb->gyro_y_dph == -2.0);
  CHECK(mb->gyro_z_dph == 3.0);
}

TEST_CASE("protocol: a three-axis unit's per-axis thermistors are fields of its samples only, null where not read") {
  Sample s;
  s.t_s = 5.0;
  s.three_axis = true;
  s.gyro_y_dph = 1.0;
  s.gyro_z_dph = 2.0;
  CHECK_FALSE(to_json(s).contains("t1_y_c"));  // axes sharing the unit's thermistors: as before
  CHECK_FALSE(sample_from_json(to_json(s))->axis_thermistors);
  s.axis_thermistors = true;
  s.t1_y_c = 24.5;
  s.t2_y_c = 24.75;
  s.t1_z_c = 23.5;  // z's outer wall not read this second
  const json j = to_json(s);
  CHECK(j["t1_y_c"] == 24.5);
  CHECK(j["t2_z_c"].is_null());
  auto back = sample_from_json(json::parse(j.dump()));
  REQUIRE(back.has_value());
  CHECK(back->axis_thermistors);
  CHECK(back->t2_y_c == 24.75);
  CHECK(back->t1_z_c == 23.5);
  CHECK_FALSE(back->t2_z_c.has_value());
  json bad = j;
  bad["t1_z_c"] = "warm";
  auto refused = sample_from_json(bad);
  REQUIRE_FALSE(refused.has_value());
  CHECK(refused.error().find("t1_z_c") != std::string::npos);

  SampleMessage m;
  m.state = "running";
  m.phase = "hold";
  m.serial = "FOG-0001";
  m.three_axis = true;
  CHECK_FALSE(to_json(m).contains("t1_y_c"));
  m.axis_thermistors = true;
  m.t1_y_c = 30.0;
  auto mb = sample_message_from_json(json::parse(to_json(m).dump()));
  REQUIRE(mb.has_value());
  CHECK(mb->axis_thermistors);
  CHECK(mb->t1_y_c == 30.0);
  CHECK_FALSE(mb->t2_y_c.has_value());
}
