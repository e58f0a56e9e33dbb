// The rate table served by the real fogbench-sim (--rate-table-port), driven by the real driver
// opened from the ready line's rate_table_config, with the faults switched on its control
// socket (table_fault, drop_table). Time is the bench's (wall clock x --time-scale), so the
// waits have deadlines.
#include <catch2/catch.hpp>

#include <cmath>
#include <thread>

#include "fogbench/drivers/rate_table_registry.hpp"
#include "mock_process.hpp"

using namespace fogbench::drivers;
using mockbench::MockProcess;
using mockbench::wait_for;
using namespace std::chrono_literals;

TEST_CASE("fogbench-sim --rate-table-port: the driver spins the served table, sees its fault and its link drop") {
  MockProcess mock({"--rate-table-port", "0", "--time-scale", "100"});
  auto j = mock.ready()["rate_table_config"];
  REQUIRE(j.is_object());
  j["link"]["response_timeout_ms"] = 1000;
  j["link"]["backoff"] = {{"initial_ms", 20}, {"max_ms", 200}, {"multiplier", 2}};
  j["max_accel_dps2"] = 100;
  auto cfg = parse_rate_table_config(j, "rate_table");
  INFO((cfg ? std::string() : cfg.error().to_string()));
  REQUIRE(cfg);
  auto table = open_rate_table(*cfg);
  REQUIRE(table);
  REQUIRE((*table)->set_rate_dps(100));  // 1 simulated s of ramp: 10 ms
  CHECK(wait_for(10s, [&] {
    auto s = (*table)->read_status();
    return s && s->at_rate && std::fabs(s->rate_dps - 100.0) < 0.01;
  }));
  CHECK(mock.status()["rate_table"]["clients"] == 1);

  mock.fault({{"cmd", "fault"}, {"name", "table_fault"}, {"text", "OVERSPEED TRIP"}});
  auto s = (*table)->read_status();
  REQUIRE(s);
  CHECK(s->fault);
  CHECK(s->fault_text == "OVERSPEED TRIP");
  auto events = (*table)->take_events();
  REQUIRE(events.size() == 1);
  CHECK(events[0].kind == RateTableEvent::Kind::fault);
  CHECK(mock.status()["faults"].dump().find("table_fault") != std::string::npos);
  mock.fault({{"cmd", "fault"}, {"name", "table_fault"}, {"on", false}});

  mock.fault({{"cmd", "fault"}, {"name", "drop_table"}});
  // The drop is done on the bench's next loop round; the first read after it fails.
  CHECK(wait_for(10s, [&] { return !(*table)->read_status(); }));
  events = (*table)->take_events();
  REQUIRE_FALSE(events.empty());
  CHECK(events.back().kind == RateTableEvent::Kind::link_lost);
  CHECK(wait_for(10s, [&] { return (*table)->read_status().has_value(); }));
  events = (*table)->take_events();
  REQUIRE_FALSE(events.empty());
  CHECK(events.back().kind == RateTableEvent::Kind::link_restored);
}

TEST_CASE("fogbench-sim without --rate-table-port: the table's faults are refused, not ignored") {
  MockProcess mock;
  CHECK(mock.ready()["rate_table_config"].is_null());
  const auto reply = mock.control({{"cmd", "fault"}, {"name", "table_fault"}, {"text", "OVERSPEED TRIP"}});
  CHECK(reply["ok"] == false);
  CHECK(reply["error"] == "table_fault: no rate table is served (--rate-table-port)");
}

TEST_CASE("fogbench-sim --paced --rate-table-port: the table moves with the simulated clock, not the wall's") {
  MockProcess mock({"--paced", "--rate-table-port", "0", "--time-scale", "1000"});
  auto j = mock.ready()["rate_table_config"];
  REQUIRE(j.is_object());
  j["max_accel_dps2"] = 50;  // 100 deg/s reached 2 simulated seconds after the command
  auto cfg = parse_rate_table_config(j, "rate_table");
  INFO((cfg ? std::string() : cfg.error().to_string()));
  REQUIRE(cfg);
  auto table = open_rate_table(*cfg);
  REQUIRE(table);
  REQUIRE((*table)->set_rate_dps(100));
  // Left alone, the bench's time stands still: at K = 1000, 300 ms of wall would be 300
  // simulated seconds, far past the ramp, if the table kept the wall clock.
  std::this_thread::sleep_for(300ms);
  auto s = (*table)->read_status();
  REQUIRE(s);
  CHECK_FALSE(s->at_rate);
  CHECK(std::fabs(s->rate_dps) < 1.0);
  CHECK(mock.status()["rate_table"]["time_s"] == 0.0);
  // One simulated second: half way up the ramp; three: at rate.
  REQUIRE(mock.control({{"cmd", "advance"}, {"seconds", 1}})["ok"] == true);
  s = (*table)->read_status();
  REQUIRE(s);
  CHECK(s->rate_dps == Approx(50.0).margin(1.0));
  REQUIRE(mock.control({{"cmd", "advance"}, {"seconds", 2}})["ok"] == true);
  s = (*table)->read_status();
  REQUIRE(s);
  CHECK(s->at_rate);
  CHECK(s->rate_dps == Approx(100.0).margin(0.01));
  CHECK(mock.status()["rate_table"]["time_s"] == 3.0);
}
