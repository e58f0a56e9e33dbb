// The command table (handler.cpp): every socket command has its access declared, the read-only
// side refuses every control command of the table and serves every read one, the table is what
// dispatch reads (no command of it falls through to unknown_command), and docs/protocol.md
// lists each command under the access the table gives it.
#include "fixture.hpp"

#include <fstream>
#include <regex>
#include <set>
#include <sstream>

#include "fogbench/daemon/handler.hpp"

using namespace fogbench;
using namespace fogbench::daemon;
using namespace fogbench::daemon::test;
using nlohmann::json;

namespace {
struct Rig {
  storage::Store store = memory_store();
  Station station{golden_config(), store};
  Handler handler{station};
  SessionState session;
  json send(const json& req) { return handler.handle(req, session); }
};

std::set<std::string> names_with(Access access) {
  std::set<std::string> out;
  for (const auto& c : commands())
    if (c.access == access) out.insert(std::string(c.name));
  return out;
}

// The backquoted names in `text` that look like commands (a dot, or one of the three words).
std::set<std::string> command_names_in(const std::string& text) {
  std::set<std::string> out;
  static const std::regex name(R"(`([a-z_]+(\.[a-z_]+)?)`)");
  for (auto it = std::sregex_iterator(text.begin(), text.end(), name); it != std::sregex_iterator(); ++it) out.insert((*it)[1]);
  return out;
}
}  // namespace

TEST_CASE("commands: the table has every command once, each with its access, and the lookups read it") {
  const auto all = commands();
  REQUIRE(all.size() >= 27u);
  std::set<std::string> seen;
  for (const auto& c : all) {
    INFO(c.name);
    CHECK(seen.insert(std::string(c.name)).second);
    CHECK((c.access == Access::read || c.access == Access::control));
    REQUIRE(find_command(c.name) == &c);
    CHECK(is_control_command(c.name) == (c.access == Access::control));
    CHECK(Handler::offloaded(c.name) == c.offloaded);
  }
  CHECK(find_command("launch") == nullptr);
  CHECK(find_command("") == nullptr);
  CHECK_FALSE(is_control_command("launch"));
  CHECK_FALSE(Handler::offloaded("launch"));
  // Read and control together are the whole table.
  CHECK(names_with(Access::read).size() + names_with(Access::control).size() == all.size());
}

TEST_CASE("commands: a read-only connection without a token refuses every control command of the table, and changes nothing") {
  Rig r;
  r.session.may_control = false;
  std::int64_t id = 0;
  for (const auto& c : commands()) {
    INFO(c.name);
    const json reply = r.send({{"id", ++id}, {"cmd", c.name}});
    REQUIRE(reply["type"] == "reply");
    CHECK(reply["id"] == id);
    if (c.access == Access::control) {
      REQUIRE(reply.contains("error"));
      CHECK(reply["error"]["code"] == "forbidden");
      CHECK(reply["error"]["message"] == std::string(c.name) + ": only on the local socket; this connection may only read");
    } else {
      // A read command is served: whatever it answers (a missing argument, no such run), not forbidden.
      CHECK((!reply.contains("error") || reply["error"]["code"] != "forbidden"));
    }
  }
  CHECK(r.store.list_runs()->empty());
  CHECK(r.station.active_run_id() == std::nullopt);
}

TEST_CASE("commands: with a token configured, a read-only connection refuses every control command without it or with a wrong one") {
  Rig r;
  r.session.may_control = false;
  r.session.control_token = "0123456789abcdef-secret";
  std::int64_t id = 0;
  for (const auto& c : commands()) {
    if (c.access != Access::control) continue;
    INFO(c.name);
    for (const json& token : {json(nullptr), json("wrong-0123456789abcdef"), json("0123456789abcdef-secre")}) {
      json req = {{"id", ++id}, {"cmd", c.name}};
      if (!token.is_null()) req["token"] = token;
      const json reply = r.send(req);
      REQUIRE(reply.contains("error"));
      CHECK(reply["error"]["code"] == "forbidden");
      CHECK(reply["error"]["message"] == std::string(c.name) + ": needs a valid token on this connection");
    }
    // With the token the command is let through to its own checks (its arguments are missing
    // here, or there is nothing to act on): whatever it answers, not forbidden.
    const json let = r.send({{"id", ++id}, {"cmd", c.name}, {"token", "0123456789abcdef-secret"}});
    CHECK((!let.contains("error") || let["error"]["code"] != "forbidden"));
  }
  CHECK(r.store.list_runs()->empty());
}

TEST_CASE("commands: every command of the table is dispatched on the local socket (none is unknown_command)") {
  Rig r;
  std::int64_t id = 0;
  for (const auto& c : commands()) {
    INFO(c.name);
    const json reply = r.send({{"id", ++id}, {"cmd", c.name}});
    REQUIRE(reply["type"] == "reply");
    CHECK((!reply.contains("error") || (reply["error"]["code"] != "unknown_command" && reply["error"]["code"] != "forbidden")));
  }
  const json unknown = r.send({{"id", ++id}, {"cmd", "launch"}});
  CHECK(unknown["error"]["code"] == "unknown_command");
  CHECK(unknown["error"]["message"] == "unknown command: launch");
}

TEST_CASE("commands: docs/protocol.md lists every command of the table under the access the table gives it") {
  std::ifstream f(std::string(FOGBENCH_SOURCE_DIR) + "/docs/protocol.md");
  REQUIRE(f);
  std::stringstream ss;
  ss << f.rdbuf();
  const std::string doc = ss.str();
  // The paragraph "**Read-only and control commands.** Read-only: ... Control (...): ... On the".
  const auto start = doc.find("**Read-only and control commands.**");
  REQUIRE(start != std::string::npos);
  const auto control_at = doc.find("Control (they", start);
  REQUIRE(control_at != std::string::npos);
  const auto end = doc.find("On the\nUnix socket", control_at);
  REQUIRE(end != std::string::npos);
  std::set<std::string> documented_read = command_names_in(doc.substr(start, control_at - start));
  std::set<std::string> documented_control = command_names_in(doc.substr(control_at, end - control_at));
  CHECK(documented_read == names_with(Access::read));
  CHECK(documented_control == names_with(Access::control));
}

TEST_CASE("commands: the handler fuzzer's dictionary names every command of the table") {
  std::ifstream f(std::string(FOGBENCH_SOURCE_DIR) + "/fuzz/dict/handler.dict");
  REQUIRE(f);
  std::set<std::string> lines;
  for (std::string line; std::getline(f, line);) lines.insert(line);
  for (const auto& c : commands()) {
    INFO(c.name);
    CHECK(lines.contains("\"\\\"" + std::string(c.name) + "\\\"\""));
  }
}
