// fogbenchd's configuration: the golden one parses; each refusal names its field.
#include "fixture.hpp"
#include "fogbench/drivers/chamber_registry.hpp"

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
  CHECK_THAT(refusal({{"analysis", {{"causal_lags", "yes"}}}}), Catch::StartsWith("analysis.causal_lags: expected true or false"));
  CHECK_THAT(refusal({{"colour", "blue"}}), Catch::StartsWith("colour: unknown field"));
  // The driver refuses setpoints above 180 degC by default: limits beyond it are an error.
  CHECK_THAT(refusal({{"chamber_limits", {{"max_c", 190}}}}), Catch::StartsWith("chamber_limits.max_c: above drivers"));
  CHECK_THAT(refusal({{"drivers", {{"units", {{{"serial", "X"}}}}}}}), Catch::StartsWith("drivers.units[0]"));
}

TEST_CASE("config: a slot's default serial and station.id are checked as every stored name, naming the field") {
  // Both are stored with runs and shown by status, fogctl and certificates (issue 27, point 8):
  // printable UTF-8 within storage::kMaxNameBytes, as a serial or a name a request gives.
  auto with_serial = [](const std::string& serial) {
    auto j = golden_config_json();
    j["drivers"]["units"][1]["serial"] = serial;
    auto c = parse_daemon_config(j, golden_dir());
    return c ? std::string() : c.error();
  };
  CHECK(with_serial("FOG-0002-\xc3\xa9").empty());  // printable, whatever the script
  CHECK(with_serial("FOG\x1b[2J") == "drivers.units[1].serial: control character 0x1B at byte 4");
  CHECK(with_serial("FOG\x07") == "drivers.units[1].serial: control character 0x07 at byte 4");
  CHECK(with_serial(std::string(65, 'F')) == "drivers.units[1].serial: longer than 64 bytes (65)");
  CHECK(with_serial(std::string(64, 'F')).empty());
  CHECK(with_serial("FOG-\xff") == "drivers.units[1].serial: not valid UTF-8 at byte 5");

  CHECK(refusal({{"station", {{"id", "line\r\n2"}}}}) == "station.id: control character 0x0D at byte 5");
  CHECK(refusal({{"station", {{"id", std::string(65, 's')}}}}) == "station.id: longer than 64 bytes (65)");
  CHECK(refusal({{"station", {{"id", "line-\xc3"}}}}) == "station.id: not valid UTF-8 at byte 6");
  auto ok = fogbench::daemon::test::golden_config({{"station", {{"id", "line-2"}}}});
  CHECK(ok.station_id == "line-2");
}

TEST_CASE("config: link_loss and tracking, their defaults and errors naming the field") {
  auto c = parse_daemon_config(golden_config_json(), golden_dir());
  REQUIRE(c.has_value());
  CHECK(c->link_loss.policy == LinkLossConfig::Policy::hold);
  CHECK(c->link_loss.tolerance_s == 60);
  CHECK(c->tracking.max_error_c == 5);
  CHECK(c->tracking.for_s == 600);
  CHECK(c->tracking.frozen_s == 300);
  auto j = golden_config_json();
  j.merge_patch({{"link_loss", {{"policy", "safe_abort"}, {"tolerance_s", 5}}},
                 {"tracking", {{"max_error_c", 2.5}, {"for_s", 60}, {"frozen_s", 30}}}});
  auto d = parse_daemon_config(j, golden_dir());
  REQUIRE(d.has_value());
  CHECK(d->link_loss.policy == LinkLossConfig::Policy::safe_abort);
  CHECK(d->link_loss.tolerance_s == 5);
  CHECK(d->tracking.max_error_c == 2.5);
  CHECK(d->tracking.for_s == 60);
  CHECK(d->tracking.frozen_s == 30);

  CHECK_THAT(refusal({{"link_loss", {{"policy", "pray"}}}}), Catch::StartsWith("link_loss.policy"));
  CHECK_THAT(refusal({{"link_loss", {{"tolerance_s", -1}}}}), Catch::StartsWith("link_loss.tolerance_s"));
  CHECK_THAT(refusal({{"link_loss", {{"tolerance", 1}}}}), Catch::StartsWith("link_loss.tolerance: unknown field"));
  CHECK_THAT(refusal({{"link_loss", 3}}), Catch::StartsWith("link_loss: expected an object"));
  CHECK_THAT(refusal({{"tracking", {{"max_error_c", 0}}}}), Catch::StartsWith("tracking.max_error_c"));
  CHECK_THAT(refusal({{"tracking", {{"for_s", "long"}}}}), Catch::StartsWith("tracking.for_s"));
  CHECK_THAT(refusal({{"tracking", {{"frozen_s", -3}}}}), Catch::StartsWith("tracking.frozen_s"));
}

TEST_CASE("config: the chamber's reconnection back-off is capped so an outage shorter than the tolerance is survived") {
  for (double tolerance_s : {10.0, 60.0, 300.0}) {
    auto j = golden_config_json();
    j.merge_patch({{"link_loss", {{"tolerance_s", tolerance_s}}}});
    auto c = parse_daemon_config(j, golden_dir());
    REQUIRE(c.has_value());
    const auto& b = c->drivers.chamber.modbus.backoff;
    INFO("tolerance " << tolerance_s << " s, max_ms " << b.max_ms);
    CHECK(b.max_ms <= static_cast<std::int64_t>(tolerance_s * 100.0));
    CHECK(b.max_ms >= b.initial_ms);
    CHECK(c->drivers.chamber.line.backoff.max_ms == b.max_ms);
    // An outage of up to 0.9 x the tolerance less one reply timeout: the link is tried again
    // every back-off delay, each failure costing a timeout; the first attempt after the chamber
    // is back succeeds before the tolerance runs out.
    const double timeout_s = c->drivers.chamber.modbus.response_timeout_ms / 1000.0;
    for (double outage_s = 1.0; outage_s < 0.9 * tolerance_s - timeout_s; outage_s += tolerance_s / 20.0) {
      fogbench::drivers::Backoff backoff(b);
      using std::chrono::milliseconds;
      const auto t0 = fogbench::drivers::Backoff::TimePoint{};
      auto at = [&](double s) { return t0 + milliseconds(static_cast<std::int64_t>(s * 1000.0)); };
      double now_s = 0.0;
      for (;;) {
        while (!backoff.may_attempt(at(now_s))) now_s += 0.001;
        if (now_s >= outage_s) break;     // the chamber answers again
        now_s += timeout_s;               // the attempt waits out its reply timeout
        backoff.record_failure(at(now_s));
      }
      INFO("outage " << outage_s << " s: back at " << now_s << " s");
      CHECK(now_s < tolerance_s);
    }
  }
  // The safe_abort policy aborts at once: nothing to cap. A configured max below the cap stays.
  auto j = golden_config_json();
  j.merge_patch({{"drivers", {{"chamber", {{"modbus", {{"backoff", {{"initial_ms", 100}, {"max_ms", 2000}}}}}}}}}});
  auto c = parse_daemon_config(j, golden_dir());
  REQUIRE(c.has_value());
  CHECK(c->drivers.chamber.modbus.backoff.max_ms == 2000);
}

TEST_CASE("config: socket.group, socket.tcp and the token, with errors naming the field") {
  auto j = golden_config_json();
  j.merge_patch({{"socket", {{"group", "root"}, {"tcp", {{"port", 7000}, {"token", "0123456789abcdef"}}}}}});
  auto c = parse_daemon_config(j, golden_dir());
  REQUIRE(c.has_value());
  CHECK(c->socket.group == "root");
  CHECK(c->socket.tcp_port == 7000);
  CHECK(c->socket.tcp_address == "127.0.0.1");  // loopback unless said otherwise
  CHECK(c->socket.tcp_token == "0123456789abcdef");
  // The configuration stored with runs does not carry the token.
  CHECK(c->source["socket"]["tcp"]["token"] == "(redacted)");

  CHECK_THAT(refusal({{"socket", {{"group", "no-such-group-fogbench"}}}}), Catch::StartsWith("socket.group: no such group"));
  CHECK_THAT(refusal({{"socket", {{"tcp", {{"port", 0}}}}}}), Catch::StartsWith("socket.tcp.port"));
  CHECK_THAT(refusal({{"socket", {{"tcp", {{"port", 7000}, {"address", "localhost!"}}}}}}), Catch::StartsWith("socket.tcp.address"));
  CHECK_THAT(refusal({{"socket", {{"tcp", {{"port", 7000}, {"token", "short"}}}}}}), Catch::StartsWith("socket.tcp.token"));
  CHECK_THAT(refusal({{"socket", {{"tcp", {{"port", 7000}, {"token_file", "nope.token"}}}}}}), Catch::StartsWith("socket.tcp.token_file"));
  // The one unknown-field check (drivers/known_fields.hpp): the field's path, then the section's fields.
  CHECK(refusal({{"socket", {{"tcp", {{"port", 7000}, {"tokn", "x"}}}}}}) ==
        "socket.tcp.tokn: unknown field (known: port, address, token, token_file, allow_remote)");
  CHECK_THAT(refusal({{"socket", {{"tcp_port", 7000}, {"tcp", {{"port", 7001}}}}}}), Catch::StartsWith("socket.tcp_port"));
}

TEST_CASE("config: a non-loopback socket.tcp.address needs allow_remote and a token") {
  auto refusal = [](const nlohmann::json& tcp) {
    nlohmann::json j = golden_config_json();
    j["socket"]["tcp"] = tcp;
    auto c = parse_daemon_config(j, golden_dir());
    REQUIRE_FALSE(c.has_value());
    return c.error();
  };
  auto accepted = [](const nlohmann::json& tcp) {
    nlohmann::json j = golden_config_json();
    j["socket"]["tcp"] = tcp;
    auto c = parse_daemon_config(j, golden_dir());
    INFO((c ? std::string() : c.error()));
    return c.has_value();
  };
  const std::string token = "0123456789abcdef";
  for (const char* any : {"0.0.0.0", "::", "192.0.2.7", "2001:db8::7"}) {
    INFO(any);
    // Bound silently before, token or not.
    CHECK_THAT(refusal({{"port", 7000}, {"address", any}}),
               Catch::StartsWith(std::string("socket.tcp.address: ") + any + " is not a loopback address"));
    CHECK_THAT(refusal({{"port", 7000}, {"address", any}, {"token", token}}),
               Catch::StartsWith("socket.tcp.address: "));
    CHECK_THAT(refusal({{"port", 7000}, {"address", any}, {"allow_remote", true}}),
               Catch::StartsWith("socket.tcp.allow_remote: a non-loopback address"));
    CHECK(accepted({{"port", 7000}, {"address", any}, {"allow_remote", true}, {"token", token}}));
  }
  CHECK_THAT(refusal({{"port", 7000}, {"allow_remote", "yes"}}), Catch::StartsWith("socket.tcp.allow_remote: expected true or false"));
  // Loopback needs neither.
  CHECK(accepted({{"port", 7000}}));
  CHECK(accepted({{"port", 7000}, {"address", "::1"}}));
  CHECK(accepted({{"port", 7000}, {"address", "127.0.0.2"}}));
}

TEST_CASE("config: on the accelerated clock the reconnection backoff is divided by the time scale") {
  auto c = parse_daemon_config(golden_config_json(), golden_dir());
  REQUIRE(c.has_value());
  auto& d = c->drivers;
  d.chamber.modbus.backoff = {250, 30000, 2.0};
  d.thermistors.modbus.backoff = {100, 10000, 3.0};
  auto same = d;
  scale_backoff_to_clock(same, 1.0);
  CHECK(same.chamber.modbus.backoff.max_ms == 30000);
  scale_backoff_to_clock(same, 0.5);  // slower than real time: left as configured
  CHECK(same.chamber.modbus.backoff.initial_ms == 250);

  scale_backoff_to_clock(d, 50.0);
  // 250 ms / 50 = 5 ms and 30 s / 50 = 600 ms: the same run time as at 1x.
  CHECK(d.chamber.modbus.backoff.initial_ms == 5);
  CHECK(d.chamber.modbus.backoff.max_ms == 600);
  CHECK(d.chamber.modbus.backoff.multiplier == 2.0);
  CHECK(d.thermistors.modbus.backoff.initial_ms == 2);
  CHECK(d.thermistors.modbus.backoff.max_ms == 200);
  CHECK(d.thermistors.modbus.backoff.multiplier == 3.0);
  // Never below 1 ms, however fast the clock.
  scale_backoff_to_clock(d, 1e6);
  CHECK(d.chamber.modbus.backoff.initial_ms == 1);
  CHECK(d.chamber.modbus.backoff.max_ms == 1);
}

TEST_CASE("config: the gyro bus is retried after a second of run time, 1 s of wall time divided by the time scale") {
  using std::chrono::milliseconds;
  CHECK(gyro_retry_delay(1.0) == milliseconds(1000));
  CHECK(gyro_retry_delay(0.5) == milliseconds(1000));  // slower than real time: a wall second
  CHECK(gyro_retry_delay(200.0) == milliseconds(5));   // 1000 ms / 200
  CHECK(gyro_retry_delay(3.0) == milliseconds(333));   // 333.3 rounded
  CHECK(gyro_retry_delay(1e6) == milliseconds(1));     // never below 1 ms
}

TEST_CASE("config: sim_clock, the paced mock bench's control socket, only on a simulated bench") {
  auto j = golden_config_json();
  j["simulated"] = true;
  j["sim_clock"] = "mock-control.sock";
  auto c = parse_daemon_config(j, golden_dir());
  INFO((c ? std::string("ok") : c.error()));
  REQUIRE(c.has_value());
  REQUIRE(c->sim_clock.has_value());
  CHECK(*c->sim_clock == golden_dir() / "mock-control.sock");  // relative to the file's folder
  j["simulated"] = false;
  CHECK(parse_daemon_config(j, golden_dir()).error().starts_with("sim_clock: only with"));
  j["simulated"] = true;
  j["sim_clock"] = 3;
  CHECK(parse_daemon_config(j, golden_dir()).error().starts_with("sim_clock: expected the path"));
}

TEST_CASE("config: rate_table, optional, its kind and fields refused by name") {
  auto none = parse_daemon_config(golden_config_json(), golden_dir());
  REQUIRE(none.has_value());
  CHECK_FALSE(none->rate_table.has_value());
  auto j = golden_config_json();
  j["rate_table"] = {{"kind", "acutrol"}, {"link", {{"transport", "tcp"}, {"host", "127.0.0.1"}, {"port", 9888}}}, {"max_rate_dps", 300}};
  auto c = parse_daemon_config(j, golden_dir());
  INFO((c ? std::string() : c.error()));
  REQUIRE(c.has_value());
  REQUIRE(c->rate_table.has_value());
  CHECK(c->rate_table->kind == "acutrol");
  CHECK(c->rate_table->line.port == 9888);
  CHECK(c->rate_table->limits.max_rate_dps == 300);
  CHECK_THAT(refusal({{"rate_table", {{"kind", "spinny"}, {"link", {{"transport", "tcp"}, {"port", 1}}}}}}),
             Catch::StartsWith("rate_table.kind") && Catch::Contains("acutrol"));
  CHECK_THAT(refusal({{"rate_table", {{"kind", "acutrol"}, {"link", {{"transport", "tcp"}, {"port", 1}}}, {"speed", 3}}}}),
             Catch::Contains("rate_table.speed"));
  CHECK_THAT(refusal({{"rate_table", {{"kind", "acutrol"}}}}), Catch::StartsWith("rate_table.link"));
  CHECK_THAT(refusal({{"rate_table", "acutrol"}}), Catch::StartsWith("rate_table"));
}

TEST_CASE("config: an unknown chamber kind is refused at start-up, naming the field and the known kinds") {
  // The chamber is opened by its kind from the drivers' table (chamber_registry.hpp): a kind the
  // table does not hold stops the configuration, it never falls back to Modbus.
  CHECK_THAT(refusal({{"drivers", {{"chamber", {{"kind", "thermotron"}}}}}}),
             Catch::Contains("chamber.kind") && Catch::Contains("'thermotron'") &&
                 Catch::Contains("(known: " + fogbench::drivers::known_chamber_kinds() + ")"));
  // A known kind with another kind's fields (the golden chamber's Modbus ones) is refused by name.
  CHECK_THAT(refusal({{"drivers", {{"chamber", {{"kind", "espec"}, {"link", {{"transport", "tcp"}, {"host", "127.0.0.1"}}}}}}}}),
             Catch::Contains("chamber.") && Catch::Contains("unknown field"));
}
