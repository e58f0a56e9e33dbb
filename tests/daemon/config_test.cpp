// fogbenchd's configuration: the golden one parses; each refusal names its field.
#include "fixture.hpp"

using namespace fogbench::daemon;
using fogbench::daemon::test::golden_config_json;
using fogbench::daemon::test::golden_dir;

namespace {
std::string refusal(nlohmann::json patch) {
  auto j = golden_config_json();
  j.merge_patch(patch);
  auto c = parse_daemon_config(j, golden_dir());
  REQUIRE_FALSE(c.has_value());
  return c.error();
}
}  // namespace

TEST_CASE("config: the golden configuration parses with paths resolved against its folder") {
  auto c = parse_daemon_config(golden_config_json(), golden_dir());
  REQUIRE(c.has_value());
  CHECK(c->simulated);
  CHECK(c->limits.max_c == 60);
  CHECK(c->safe_setpoint_c == 20);
  CHECK(c->profile_dir == golden_dir() / "profiles");
  CHECK(c->drivers.units.size() == 2);
  CHECK(c->storage_path == ":memory:");
  CHECK(!c->socket.tcp_port);
}

TEST_CASE("config: errors name the field") {
  CHECK_THAT(refusal({{"chamber_limits", {{"max_c", "hot"}}}}), Catch::StartsWith("chamber_limits.max_c"));
  CHECK_THAT(refusal({{"chamber_limits", {{"min_c", 70}}}}), Catch::StartsWith("chamber_limits.min_c"));
  CHECK_THAT(refusal({{"safe_setpoint_c", 100}}), Catch::StartsWith("safe_setpoint_c"));
  CHECK_THAT(refusal({{"safe_setpoint_c", nullptr}}), Catch::StartsWith("safe_setpoint_c"));
  CHECK_THAT(refusal({{"simulated", "yes"}}), Catch::StartsWith("simulated"));
  CHECK_THAT(refusal({{"socket", {{"tcp_port", 70000}}}}), Catch::StartsWith("socket.tcp_port"));
  CHECK_THAT(refusal({{"storage", {{"synchronous", "sometimes"}}}}), Catch::StartsWith("storage.synchronous"));
  CHECK_THAT(refusal({{"analysis", {{"method", "magic"}}}}), Catch::StartsWith("analysis.method"));
  CHECK_THAT(refusal({{"analysis", {{"terms", "T1 +"}}}}), Catch::StartsWith("analysis.terms"));
  CHECK_THAT(refusal({{"colour", "blue"}}), Catch::StartsWith("colour: unknown field"));
  // The driver refuses setpoints above 180 degC by default: limits beyond it are an error.
  CHECK_THAT(refusal({{"chamber_limits", {{"max_c", 190}}}}), Catch::StartsWith("chamber_limits.max_c: above drivers"));
  CHECK_THAT(refusal({{"drivers", {{"units", {{{"serial", "X"}}}}}}}), Catch::StartsWith("drivers.units[0]"));
}
