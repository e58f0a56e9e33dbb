// The rate table's driver (ACUTROL command set) against a scripted line peer: the commands it
// sends, the limits it refuses before any I/O, the controller's refusals and faults it reports,
// and the configuration and registry. The driver against the mock bench's peer with the table's
// dynamics: tests/mockbench/rate_table_test.cpp.
#include <catch2/catch.hpp>

#include <nlohmann/json.hpp>

#include <atomic>
#include <fstream>
#include <sstream>

#include "fogbench/drivers/acutrol_dialect.hpp"
#include "fogbench/drivers/rate_table.hpp"
#include "fogbench/drivers/rate_table_registry.hpp"
#include "line_peer.hpp"

using namespace fogbench::drivers;
using linepeer::LinePeer;

namespace {

RateTableConfig table_config(std::uint16_t port) {
  RateTableConfig c;
  c.line.port = port;
  c.line.response_timeout_ms = 500;
  c.limits.max_rate_dps = 300;
  c.limits.max_accel_dps2 = 50;
  return c;
}

const auto fixed_time = std::chrono::system_clock::time_point(std::chrono::milliseconds(1795910400123));  // 2026-11-29T00:00:00.123Z

}  // namespace

TEST_CASE("acutrol dialect: command texts, abbreviated headers, replies") {
  CHECK(acutrol::demand_rate(1, -100.5) == ":demand:rate 1, -100.500000");
  CHECK(acutrol::read_position(2) == ":read:position 2");
  auto c = acutrol::parse_command(":D:R 1, 25.5");
  REQUIRE(c);
  CHECK(c->verb == acutrol::Verb::demand);
  CHECK(c->item == acutrol::Item::rate);
  CHECK(c->axis == 1);
  CHECK(c->value == 25.5);
  c = acutrol::parse_command(":mode:pos 1");
  REQUIRE(c);
  CHECK(c->item == acutrol::Item::position);
  std::string why;
  CHECK_FALSE(acutrol::parse_command(":demand:rate 1", &why));
  CHECK(why == "a demand needs a value");
  CHECK_FALSE(acutrol::parse_command(":demand:rate 1, fast", &why));
  CHECK(why == "expected a number after the axis, got 'fast'");
  CHECK_FALSE(acutrol::parse_command(":spin:rate 1", &why));
  CHECK(why == "unknown header ':spin'");
  CHECK_FALSE(acutrol::parse_command(":read:r", &why));
  CHECK(why == "expected an axis number, got ''");
  auto e = acutrol::parse_error("ERR 2: RATE LIMIT EXCEEDED");
  REQUIRE(e);
  CHECK(e->code == 2);
  CHECK(e->text == "RATE LIMIT EXCEEDED");
  CHECK_FALSE(acutrol::parse_error("OK"));
  CHECK(acutrol::parse_number("1.5E+02") == 150.0);
  CHECK_FALSE(acutrol::parse_number("12 deg"));
  CHECK(acutrol::parse_status("37") == 37u);
  CHECK_FALSE(acutrol::parse_status("-1"));
}

TEST_CASE("rate table config: defaults, limits and unknown fields refused by name") {
  auto cfg = parse_rate_table_config(nlohmann::json::parse(R"({"link": {"transport": "tcp", "host": "10.0.0.5"}, "max_rate_dps": 800})"),
                                     "rate_table");
  INFO((cfg ? std::string() : cfg.error().to_string()));
  REQUIRE(cfg);
  CHECK(cfg->kind == "acutrol");
  CHECK(cfg->line.port == acutrol::default_tcp_port);
  CHECK(cfg->limits.max_rate_dps == 800);
  CHECK(cfg->limits.max_accel_dps2 == 100);
  auto bad = parse_rate_table_config(nlohmann::json::parse(R"({"link": {"transport": "tcp", "host": "h"}, "max_rate_dps": -5})"), "rate_table");
  REQUIRE_FALSE(bad);
  CHECK(bad.error().message == "rate_table.max_rate_dps: expected a number above 0 and at most 100000 (got -5)");
  bad = parse_rate_table_config(nlohmann::json::parse(R"({"kind": "aero4000", "link": {"transport": "tcp", "host": "h"}})"), "rate_table");
  REQUIRE_FALSE(bad);
  CHECK(bad.error().message == "rate_table.kind: unknown rate table kind 'aero4000' (known: acutrol)");
  bad = parse_rate_table_config(nlohmann::json::parse(R"({"link": {"transport": "tcp", "host": "h"}, "max_rate": 5})"), "rate_table");
  REQUIRE_FALSE(bad);
  CHECK_THAT(bad.error().message, Catch::Contains("max_rate"));
  bad = parse_rate_table_config(nlohmann::json::parse(R"({"max_rate_dps": 5})"), "rate_table");
  REQUIRE_FALSE(bad);
  CHECK(bad.error().message == "rate_table.link: missing (expected an object)");
}

TEST_CASE("rate table config: the shipped example parses") {
  std::ifstream in(FOGBENCH_SOURCE_DIR "/drivers/examples/rate-table-acutrol.json");
  REQUIRE(in);
  std::stringstream text;
  text << in.rdbuf();
  auto cfg = parse_rate_table_config(nlohmann::json::parse(text.str()), "rate_table");
  INFO((cfg ? std::string() : cfg.error().to_string()));
  REQUIRE(cfg);
  CHECK(cfg->line.describe() == "tcp 192.168.1.53:9888");
  CHECK(cfg->limits.max_rate_dps == 500);
  CHECK(cfg->limits.max_accel_dps2 == 100);
}

TEST_CASE("acutrol table: a rate beyond the configured limit is refused before any I/O, with an event") {
  LinePeer peer([](const std::string&) { return std::string("OK\r\n"); });
  auto table = open_rate_table(table_config(peer.port()), [] { return fixed_time; });
  REQUIRE(table);
  auto r = (*table)->set_rate_dps(300.5);
  REQUIRE_FALSE(r);
  CHECK(r.error().code == ErrorCode::out_of_range);
  CHECK_THAT(r.error().message, Catch::StartsWith("table acutrol (tcp 127.0.0.1:"));
  CHECK_THAT(r.error().message, Catch::EndsWith("rate 300.5 deg/s beyond the configured limit +-300 deg/s (not sent)"));
  CHECK(peer.received().empty());
  auto events = (*table)->take_events();
  REQUIRE(events.size() == 1);
  CHECK(events[0].kind == RateTableEvent::Kind::refused);
  CHECK_THAT(events[0].to_string(), Catch::StartsWith("2026-11-29T00:00:00.123Z table acutrol (tcp 127.0.0.1:"));
  CHECK_THAT(events[0].to_string(), Catch::Contains(": refused: rate 300.5 deg/s"));
  CHECK((*table)->take_events().empty());
}

TEST_CASE("acutrol table: the commands sent for a rate, a position and a stop") {
  LinePeer peer([](const std::string&) { return std::string("OK\r\n"); });
  auto table = open_rate_table(table_config(peer.port()));
  REQUIRE(table);
  REQUIRE((*table)->set_rate_dps(100));
  REQUIRE((*table)->set_rate_dps(-20));
  REQUIRE((*table)->go_to_position_deg(-90));
  REQUIRE((*table)->stop());
  CHECK(peer.received() == std::vector<std::string>{
                               ":mode:rate 1", ":demand:acceleration 1, 50.000000", ":demand:rate 1, 100.000000",
                               ":demand:rate 1, -20.000000", ":mode:position 1", ":demand:position 1, 270.000000",
                               ":mode:rate 1", ":demand:rate 1, 0.000000"});
}

TEST_CASE("acutrol table: the controller's refusal names the command and the reason") {
  LinePeer peer([](const std::string& line) {
    if (line.starts_with(":demand:rate")) return acutrol::format_error(acutrol::err_rate_limit, "RATE LIMIT EXCEEDED") + "\r\n";
    if (line.starts_with(":read:status")) return std::string("garbage\r\n");
    return std::string("OK\r\n");
  });
  auto table = open_rate_table(table_config(peer.port()));
  REQUIRE(table);
  auto r = (*table)->set_rate_dps(250);
  REQUIRE_FALSE(r);
  CHECK(r.error().code == ErrorCode::out_of_range);
  CHECK_THAT(r.error().message,
             Catch::EndsWith("): ':demand:rate 1, 250.000000' refused by the controller: 'ERR 2: RATE LIMIT EXCEEDED' "
                             "(rate demand beyond the table's rate limit)"));
  auto events = (*table)->take_events();
  REQUIRE(events.size() == 1);
  CHECK(events[0].kind == RateTableEvent::Kind::refused);
  auto s = (*table)->read_status();
  REQUIRE_FALSE(s);
  CHECK(s.error().code == ErrorCode::protocol);
  CHECK_THAT(s.error().message, Catch::EndsWith("':read:status 1' answered 'garbage', not a status word 0..65535"));
}

TEST_CASE("acutrol table: a fault in the status word is read with its text and reported once as an event") {
  std::atomic<bool> fault{true};
  LinePeer peer([&fault](const std::string& line) {
    using namespace acutrol;
    if (line.starts_with(":read:status")) {
      return std::to_string(fault ? status_fault : (status_interlock_closed | status_mode_rate)) + "\r\n";
    }
    if (line.starts_with(":read:fault")) return std::string("OVERSPEED TRIP\r\n");
    if (line.starts_with(":read:rate")) return std::string("12.5\r\n");
    if (line.starts_with(":read:position")) return std::string("45.25\r\n");
    return std::string("OK\r\n");
  });
  auto table = open_rate_table(table_config(peer.port()));
  REQUIRE(table);
  auto s = (*table)->read_status();
  REQUIRE(s);
  CHECK(s->fault);
  CHECK(s->fault_text == "OVERSPEED TRIP");
  CHECK(s->rate_dps == 12.5);
  CHECK(s->position_deg == 45.25);
  CHECK(s->mode == RateTableMode::off);
  REQUIRE((*table)->read_status());
  auto events = (*table)->take_events();
  REQUIRE(events.size() == 1);
  CHECK(events[0].kind == RateTableEvent::Kind::fault);
  CHECK(events[0].reason == "the table reports a fault: 'OVERSPEED TRIP'");
  fault = false;
  s = (*table)->read_status();
  REQUIRE(s);
  CHECK_FALSE(s->fault);
  CHECK(s->mode == RateTableMode::rate);
  events = (*table)->take_events();
  REQUIRE(events.size() == 1);
  CHECK(events[0].kind == RateTableEvent::Kind::fault_cleared);
}

TEST_CASE("acutrol table: a controller that stops answering mid-step is a timeout and one link_lost event") {
  std::atomic<bool> silent{false};
  LinePeer peer([&silent](const std::string&) { return silent ? std::string() : std::string("OK\r\n"); });
  auto cfg = table_config(peer.port());
  cfg.line.response_timeout_ms = 200;
  auto table = open_rate_table(cfg);
  REQUIRE(table);
  REQUIRE((*table)->set_rate_dps(100));
  silent = true;
  auto r = (*table)->set_rate_dps(-100);
  REQUIRE_FALSE(r);
  CHECK(r.error().code == ErrorCode::timeout);
  CHECK_THAT(r.error().message,
             Catch::EndsWith("): ':demand:rate 1, -100.000000': no whole reply within 200 ms (received nothing)"));
  auto events = (*table)->take_events();
  REQUIRE(events.size() == 1);
  CHECK(events[0].kind == RateTableEvent::Kind::link_lost);
  CHECK(events[0].reason == "link lost: ':demand:rate 1, -100.000000': no whole reply within 200 ms (received nothing)");
}
