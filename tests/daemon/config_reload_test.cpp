// The configuration's reload: the one table classifies every key the parser knows, the changed
// keys of two files split into applied and needing a restart, and a broken file's error names
// the key and its line (config_reload.hpp).
#include "fixture.hpp"

#include "fogbench/daemon/config_reload.hpp"
#include "../../daemon/src/config_fields.hpp"

using namespace fogbench::daemon;
using fogbench::daemon::test::golden_config_json;
using fogbench::daemon::test::golden_dir;
using nlohmann::json;

namespace {

std::string text_of(const json& j) { return j.dump(2); }

// A reload of the golden configuration to `patch` applied on it.
ReloadOutcome reload_to(const json& patch) {
  auto current = parse_daemon_config(golden_config_json(), golden_dir());
  REQUIRE(current.has_value());
  json next = golden_config_json();
  next.merge_patch(patch);
  auto out = plan_reload(*current, text_of(next), golden_dir());
  REQUIRE(out.has_value());
  return *out;
}

std::string reload_error(const std::string& text) {
  auto current = parse_daemon_config(golden_config_json(), golden_dir());
  REQUIRE(current.has_value());
  auto out = plan_reload(*current, text, golden_dir());
  REQUIRE_FALSE(out.has_value());
  return out.error();
}

}  // namespace

TEST_CASE("config reload: every key of every section the parser knows is classified by the table") {
  for (const auto& section : config_fields::kSections) {
    for (std::string_view key : section.keys) {
      const std::string path = config_fields::join(std::string(section.path), std::string(key));
      INFO(path);
      // A section (socket, analysis, ...): its own keys are checked as such.
      bool is_section = false;
      for (const auto& other : config_fields::kSections) is_section = is_section || other.path == path;
      if (is_section && !reload_rule_of(path)) continue;
      const ReloadRule* r = reload_rule_of(path);
      REQUIRE(r != nullptr);
      // Named by its own row, or by its section's row when the whole section needs a restart
      // (web, plant, socket.tcp, ...): never by a default.
      CHECK((r->key == path || (!section.path.empty() && r->key == section.path)));
      if (r->key == section.path) CHECK(r->cls == ReloadClass::restart);
    }
  }
  // The drivers' sections are the drivers library's: the section restarts as a whole, the
  // slots' serials and names apply.
  CHECK(reload_rule_of("drivers.chamber.modbus.host")->cls == ReloadClass::restart);
  CHECK(reload_rule_of("drivers.units[3].gyro.node_id")->cls == ReloadClass::restart);
  CHECK(reload_rule_of("drivers.units[3].thermistors.t1.address")->cls == ReloadClass::restart);
  CHECK(reload_rule_of("drivers.units")->cls == ReloadClass::restart);
  CHECK(reload_rule_of("drivers.units[0].serial")->cls == ReloadClass::applies);
  CHECK(reload_rule_of("drivers.units[12].slot")->cls == ReloadClass::applies);
  CHECK(reload_rule_of("colour") == nullptr);
}

TEST_CASE("config reload: every row of the table names a key the parser knows") {
  for (const auto& r : reload_rules()) {
    INFO(r.key);
    bool known = r.key.starts_with("drivers");
    for (const auto& section : config_fields::kSections)
      for (std::string_view key : section.keys)
        known = known || config_fields::join(std::string(section.path), std::string(key)) == r.key;
    CHECK(known);
  }
}

TEST_CASE("config reload: the classes of the keys the issue names") {
  using enum ReloadClass;
  for (const char* k : {"socket.max_clients", "socket.unix_max_clients", "socket.max_clients_per_address",
                        "socket.refusal_log_interval_s", "socket.max_analyses_per_address", "analysis.verify_threshold",
                        "analysis.terms", "drivers.units[0].serial", "drivers.units[1].slot"}) {
    INFO(k);
    CHECK(reload_rule_of(k)->cls == applies);
  }
  for (const char* k : {"storage.path", "socket.path", "socket.tcp.port", "socket.tcp_port", "drivers.chamber.modbus.port",
                        "drivers.gyro_bus.transport", "drivers.thermistors.modbus.host", "drivers.units[0].gyro.node_id",
                        "plant.conninfo", "web.listen", "link_loss.tolerance_s", "tracking.for_s", "safe_setpoint_c"}) {
    INFO(k);
    CHECK(reload_rule_of(k)->cls == restart);
  }
}

TEST_CASE("config reload: changed keys are the leaves that differ, an array of another length named itself") {
  const json a = {{"socket", {{"path", "/a"}, {"max_clients", 4}}}, {"units", {{{"serial", "A"}}, {{"serial", "B"}}}}};
  json b = a;
  CHECK(changed_keys(a, b).empty());
  b["socket"]["max_clients"] = 5;
  b["units"][1]["serial"] = "C";
  CHECK(changed_keys(a, b) == std::vector<std::string>{"socket.max_clients", "units[1].serial"});
  b = a;
  b["socket"].erase("path");
  b["analysis"] = {{"terms", "T1"}};
  CHECK(changed_keys(a, b) == std::vector<std::string>{"analysis.terms", "socket.path"});
  b = a;
  b["units"].push_back({{"serial", "D"}});
  CHECK(changed_keys(a, b) == std::vector<std::string>{"units", "units[2].serial"});
  // An empty section is the section left out; a section added is its keys.
  b = a;
  b["analysis"] = json::object();
  CHECK(changed_keys(a, b).empty());
  json c = b;
  c["analysis"]["terms"] = "T1";
  CHECK(changed_keys(b, c) == std::vector<std::string>{"analysis.terms"});
}

TEST_CASE("config reload: a default serial and a limit apply, a socket path is kept and named") {
  json next = golden_config_json();
  next["socket"]["path"] = "/tmp/elsewhere.sock";
  next["socket"]["max_clients"] = 7;
  next["drivers"]["units"][1]["serial"] = "FOG-0099";
  next["analysis"] = {{"verify_threshold", 0.1}};
  auto current = parse_daemon_config(golden_config_json(), golden_dir());
  REQUIRE(current.has_value());
  auto r = plan_reload(*current, text_of(next), golden_dir());
  REQUIRE(r.has_value());
  CHECK(r->applied == std::vector<std::string>{"analysis.verify_threshold", "drivers.units[1].serial", "socket.max_clients"});
  CHECK(r->restart == std::vector<std::string>{"socket.path"});
  // In force: the new serial, limit and threshold; the old socket path.
  CHECK(r->config.drivers.units[1].serial == "FOG-0099");
  CHECK(r->config.drivers.units[0].serial == "FOG-0001");
  CHECK(r->config.socket.max_clients == 7);
  CHECK(r->config.analysis.verify_threshold == 0.1);
  CHECK(r->config.socket.unix_path == current->socket.unix_path);
  CHECK(r->config.file_json["socket"]["path"] == golden_config_json()["socket"]["path"]);
  CHECK(r->config.source["drivers"]["units"][1]["serial"] == "FOG-0099");
  // Reported and logged by name.
  const json rep = r->report();
  CHECK(rep["changed"] == true);
  CHECK(rep["needs_restart"][0]["key"] == "socket.path");
  CHECK(rep["applied"].size() == 3);
  CHECK_THAT(r->log_line(), Catch::Contains("needs a restart (old value kept): socket.path"));
  CHECK_THAT(r->log_line(), Catch::Contains("drivers.units[1].serial"));

  // The same file again: the restart-only key is still named, nothing else.
  auto again = plan_reload(r->config, text_of(next), golden_dir());
  REQUIRE(again.has_value());
  CHECK(again->applied.empty());
  CHECK(again->restart == std::vector<std::string>{"socket.path"});
}

TEST_CASE("config reload: an unchanged file changes nothing") {
  const auto out = reload_to(json::object());
  CHECK(out.applied.empty());
  CHECK(out.restart.empty());
  CHECK(out.report()["changed"] == false);
  CHECK(out.log_line() == "configuration reloaded: nothing changed");
}

TEST_CASE("config reload: a slot added is the drivers' change, its serial not applied alone") {
  json next = golden_config_json();
  json unit = next["drivers"]["units"][1];
  unit["serial"] = "FOG-0003";
  unit["gyro"]["node_id"] = 259;
  unit["thermistors"]["t1"]["address"] = 4;
  unit["thermistors"]["t2"]["address"] = 5;
  next["drivers"]["units"].push_back(unit);
  auto current = parse_daemon_config(golden_config_json(), golden_dir());
  REQUIRE(current.has_value());
  auto r = plan_reload(*current, text_of(next), golden_dir());
  REQUIRE(r.has_value());
  CHECK(r->applied.empty());
  CHECK(std::find(r->restart.begin(), r->restart.end(), "drivers.units") != r->restart.end());
  CHECK(std::find(r->restart.begin(), r->restart.end(), "drivers.units[2].serial") != r->restart.end());
  CHECK(r->config.drivers.units.size() == 2);
}

TEST_CASE("config reload: a default serial swapped between slots applies, one in two slots is refused") {
  json next = golden_config_json();
  next["drivers"]["units"][0]["serial"] = "FOG-0002";
  next["drivers"]["units"][1]["serial"] = "FOG-0001";
  auto current = parse_daemon_config(golden_config_json(), golden_dir());
  REQUIRE(current.has_value());
  auto r = plan_reload(*current, text_of(next), golden_dir());
  REQUIRE(r.has_value());
  CHECK(r->config.drivers.units[0].serial == "FOG-0002");
  next["drivers"]["units"][1]["serial"] = "FOG-0002";
  CHECK_THAT(reload_error(text_of(next)), Catch::Contains("drivers.units"));
}

TEST_CASE("config reload: a broken file names the key and its line, or the place of a syntax error") {
  json next = golden_config_json();
  next["socket"]["max_clientz"] = 4;
  std::string text = text_of(next);
  const auto line = line_of_key(text, "socket.max_clientz");
  REQUIRE(line.has_value());
  CHECK(reload_error(text).starts_with("socket.max_clientz (line " + std::to_string(*line) + "): unknown field (known: path, group, "));

  next = golden_config_json();
  next["socket"]["max_clients"] = "many";
  text = text_of(next);
  CHECK(reload_error(text) == "socket.max_clients (line " + std::to_string(*line_of_key(text, "socket.max_clients")) +
                                  "): expected an integer 1..100000");

  // A key missing: the line of the section it is missing from.
  next = golden_config_json();
  next["storage"].erase("path");
  text = text_of(next);
  CHECK(reload_error(text) ==
        "storage.path (line " + std::to_string(*line_of_key(text, "storage")) + ", in storage): missing");

  // Bad JSON: the line and column of the byte the parser stopped at (a missing comma after
  // line 2's value: it stops at the end of line 3's "storage", column 11).
  CHECK_THAT(reload_error("{\n  \"simulated\": true\n  \"storage\": {}\n}\n"), Catch::StartsWith("line 3, column 11: not valid JSON: "));  // the end of the token it stopped at
  CHECK_THAT(reload_error("{\n  \"simulated\": tru"), Catch::StartsWith("line 2, column "));
}

TEST_CASE("config reload: the line finder follows objects, arrays and strings") {
  const std::string text =
      "{\n"                                    // 1
      "  \"a\": {\"b\": 1,\n"                  // 2
      "        \"c\": [10,\n"                  // 3
      "               {\"d\": \"x, {y}\"},\n"  // 4
      "               \"s\"]},\n"              // 5
      "  \"units\": [\n"                       // 6
      "    {\"serial\": \"A\"},\n"             // 7
      "    {\"slot\": \"B\",\n"                // 8
      "     \"serial\": \"B\\\"q\"}\n"         // 9
      "  ],\n"                                 // 10
      "  \"e\": \"b\"\n"                       // 11
      "}\n";
  CHECK(line_of_key(text, "a") == 2u);
  CHECK(line_of_key(text, "a.b") == 2u);
  CHECK(line_of_key(text, "a.c") == 3u);
  CHECK(line_of_key(text, "a.c[0]") == 3u);
  CHECK(line_of_key(text, "a.c[1]") == 4u);
  CHECK(line_of_key(text, "a.c[1].d") == 4u);
  CHECK(line_of_key(text, "a.c[2]") == 5u);
  CHECK(line_of_key(text, "units[0].serial") == 7u);
  CHECK(line_of_key(text, "units[1]") == 8u);
  CHECK(line_of_key(text, "units[1].serial") == 9u);
  CHECK(line_of_key(text, "e") == 11u);
  // A value is not a key; a key elsewhere is not this one.
  CHECK_FALSE(line_of_key(text, "b").has_value());
  CHECK_FALSE(line_of_key(text, "d").has_value());
  CHECK_FALSE(line_of_key(text, "units[2]").has_value());
  // A truncated text is scanned as far as it goes.
  CHECK(line_of_key("{\n\"a\":\n{\"b\": [1,", "a.b") == 3u);
}

TEST_CASE("config reload: a byte offset as line and column") {
  const std::string text = "ab\ncd\n\nx";
  CHECK(position_of_offset(text, 0).line == 1);
  CHECK(position_of_offset(text, 0).column == 1);
  CHECK(position_of_offset(text, 4).line == 2);
  CHECK(position_of_offset(text, 4).column == 2);
  CHECK(position_of_offset(text, 7).line == 4);
  CHECK(position_of_offset(text, 7).column == 1);
  CHECK(position_of_offset(text, 1000).line == 4);
  CHECK(position_of_offset(text, 1000).column == 2);
}

TEST_CASE("config text: a trailing comma is named at the comma's line and column, in objects and arrays") {
  auto c = parse_daemon_config_text("{\"simulated\": true,\n \"storage\": {\"path\": \"x.db\"},\n}\n", golden_dir());
  REQUIRE_FALSE(c.has_value());
  INFO(c.error());
  CHECK(c.error().starts_with("line 3, column 1: not valid JSON"));
  CHECK(c.error().find("(a trailing comma at line 2, column 29: JSON allows none before '}')") != std::string::npos);
  auto a = parse_daemon_config_text("{\"x\": [1, 2,  ]}", golden_dir());
  REQUIRE_FALSE(a.has_value());
  INFO(a.error());
  CHECK(a.error().find("(a trailing comma at line 1, column 12: JSON allows none before ']')") != std::string::npos);
  // Another syntax error is not called one.
  auto other = parse_daemon_config_text("{\"x\": [1 2]}", golden_dir());
  REQUIRE_FALSE(other.has_value());
  CHECK(other.error().find("trailing comma") == std::string::npos);
}
