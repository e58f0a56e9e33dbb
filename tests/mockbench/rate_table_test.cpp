// The mock bench's rate table: its dynamics and answers (no I/O), and the real driver
// (AcutrolRateTable, opened through the registry) against the peer's TCP listener served in this
// process on a poll() loop thread, with simulated time stepped by the test and the faults
// switched through the mock's fault control (table_fault, drop_table).
#include <catch2/catch.hpp>

#include <atomic>
#include <cmath>
#include <thread>

#include "faults.hpp"
#include "fogbench/drivers/acutrol_dialect.hpp"
#include "fogbench/drivers/acutrol_rate_table.hpp"
#include "fogbench/drivers/rate_table_registry.hpp"
#include "poll_set.hpp"
#include "rate_table.hpp"
#include "shared_state.hpp"

using namespace fogbench::drivers;
using namespace fogbench::mock;
using Catch::Detail::Approx;

namespace {

RateTableSpec quiet_spec() {
  RateTableSpec s;
  s.ripple_dps = 0;  // exact numbers
  s.max_rate_dps = 1000;
  s.max_accel_dps2 = 200;
  return s;
}

unsigned status_of(RateTableSim& t) {
  auto w = acutrol::parse_status(t.answer(":read:status 1"));
  REQUIRE(w);
  return *w;
}

// The peer served on 127.0.0.1 by a loop thread; the simulated time is the test's.
class ServedTable {
 public:
  explicit ServedTable(RateTableSpec spec)
      : server_(shared_, "127.0.0.1", 0, [this] { return sim_time_s.load(); }) {
    shared_.rate_table.emplace(spec);
    auto ok = server_.open();
    REQUIRE(ok);
    loop_ = std::thread([this] {
      PollSet set;
      while (!stop_) {
        set.clear();
        server_.watch(set);
        clients_ = server_.open_clients();
        set.wait(5);
        set.dispatch([] { return true; });
      }
    });
  }
  ~ServedTable() {
    stop_ = true;
    loop_.join();
  }

  int port() const { return server_.port(); }
  // A fault command as the control socket takes it ({"name": ..., ...}).
  void fault(nlohmann::json command) {
    command["cmd"] = "fault";
    auto cmd = parse_fault_command(command, {});
    INFO((cmd ? std::string() : cmd.error()));
    REQUIRE(cmd);
    std::lock_guard lock(shared_.mutex);
    apply_fault(shared_.faults, *cmd, 0.0);
  }
  // Waits (at most 5 s) until the loop has no client left.
  bool wait_no_clients() {
    for (int i = 0; i < 1000; ++i) {
      if (clients_.load() == 0) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    return false;
  }

  std::atomic<double> sim_time_s{0.0};

 private:
  SharedState shared_;
  RateTableServer server_;
  std::atomic<bool> stop_{false};
  std::atomic<std::size_t> clients_{0};
  std::thread loop_;
};

}  // namespace

// ---- the dynamics and answers, no I/O --------------------------------------------------------

TEST_CASE("mock rate table: the rate ramps to its demand at the acceleration, the position integrates it") {
  RateTableSim t(quiet_spec());
  CHECK(t.answer(":mode:rate 1") == "OK\r\n");
  CHECK(t.answer(":demand:acceleration 1, 50") == "OK\r\n");
  CHECK(t.answer(":demand:rate 1, 100") == "OK\r\n");
  t.advance_to(1.0);
  CHECK(t.rate_dps() == Approx(50.0));
  CHECK(t.position_deg() == Approx(25.0));
  CHECK((status_of(t) & acutrol::status_at_rate) == 0);
  CHECK((status_of(t) & acutrol::status_moving) != 0);
  t.advance_to(3.0);
  CHECK(t.rate_dps() == 100.0);
  CHECK(t.position_deg() == Approx(200.0));  // 100 deg ramping over 2 s, then 100 deg in 1 s
  CHECK((status_of(t) & acutrol::status_at_rate) != 0);
  CHECK(t.answer(":R:R 1") == "100.000000\r\n");  // abbreviated headers, as the controller takes them
  t.advance_to(4.0);
  CHECK(t.answer(":read:position 1") == "300.000000\r\n");
  t.advance_to(5.0);
  CHECK(t.position_deg() == Approx(40.0));  // wrapped at 360 deg
  // Down to -100 deg/s: 4 s at 50 deg/s^2.
  CHECK(t.answer(":demand:rate 1, -100") == "OK\r\n");
  t.advance_to(7.0);
  CHECK(t.rate_dps() == Approx(0.0).margin(1e-9));
  t.advance_to(9.0);
  CHECK(t.rate_dps() == -100.0);
}

TEST_CASE("mock rate table: the ripple is a small sinusoid on the actual rate while moving") {
  RateTableSpec spec = quiet_spec();
  spec.ripple_dps = 0.002;
  spec.ripple_hz = 2.0;
  RateTableSim t(spec);
  CHECK(t.answer(":read:rate 1") == "0.000000\r\n");  // at rest: no ripple
  t.answer(":mode:rate 1");
  t.answer(":demand:rate 1, 10");
  t.advance_to(10.125);  // sin(2 pi 2 10.125) = 1
  CHECK(t.smooth_rate_dps() == 10.0);
  CHECK(t.rate_dps() == Approx(10.002));
  t.advance_to(10.375);  // sin = -1
  CHECK(t.rate_dps() == Approx(9.998));
  CHECK((status_of(t) & acutrol::status_at_rate) != 0);  // the demand is reached; the ripple stays
}

TEST_CASE("mock rate table: a rate beyond its limit is refused as the controller does, the demand kept") {
  RateTableSim t(quiet_spec());
  CHECK(t.answer(":demand:rate 1, 10") == "ERR 6: NOT IN RATE MODE\r\n");
  t.answer(":mode:rate 1");
  t.answer(":demand:rate 1, 10");
  CHECK(t.answer(":demand:rate 1, 1000.5") == "ERR 2: RATE LIMIT EXCEEDED, MAX 1000.000000\r\n");
  CHECK(t.answer(":demand:rate 1, -1001") == "ERR 2: RATE LIMIT EXCEEDED, MAX 1000.000000\r\n");
  CHECK(t.answer(":demand:acceleration 1, 250") == "ERR 3: ACCELERATION LIMIT 200.000000\r\n");
  CHECK(t.answer(":demand:rate 2, 10") == "ERR 1: NO AXIS 2\r\n");
  CHECK(t.answer(":spin 1") == "ERR 1: SYNTAX: no second header node\r\n");
  t.advance_to(100);
  CHECK(t.rate_dps() == 10.0);
}

TEST_CASE("mock rate table: a fault brakes the table and holds it until the interlock is reset") {
  RateTableSim t(quiet_spec());
  t.answer(":mode:rate 1");
  t.answer(":demand:rate 1, 100");
  t.advance_to(10);
  t.set_fault_condition(true, "OVERSPEED TRIP");
  const auto w = status_of(t);
  CHECK((w & acutrol::status_fault) != 0);
  CHECK((w & acutrol::status_interlock_closed) == 0);
  CHECK((w & acutrol::status_mode_rate) == 0);
  CHECK(t.answer(":read:fault 1") == "OVERSPEED TRIP\r\n");
  t.advance_to(10.25);
  CHECK(t.rate_dps() == Approx(50.0));  // braking at its 200 deg/s^2 limit
  t.advance_to(11);
  CHECK(t.rate_dps() == 0.0);
  CHECK(t.answer(":mode:rate 1") == "ERR 4: FAULT ACTIVE: OVERSPEED TRIP\r\n");
  CHECK(t.answer(":interlock:reset 1") == "ERR 4: FAULT STILL PRESENT: OVERSPEED TRIP\r\n");
  t.set_fault_condition(false, "");
  CHECK(t.answer(":read:fault 1") == "OVERSPEED TRIP\r\n");  // latched
  CHECK(t.answer(":interlock:reset 1") == "OK\r\n");
  CHECK(t.answer(":read:fault 1") == "NONE\r\n");
  CHECK(t.answer(":mode:rate 1") == "ERR 5: INTERLOCK OPEN\r\n");
  CHECK(t.answer(":interlock:close 1") == "OK\r\n");
  CHECK(t.answer(":mode:rate 1") == "OK\r\n");
}

TEST_CASE("mock rate table: a position move goes the shortest way and stops on the demand") {
  RateTableSim t(quiet_spec());
  t.answer(":mode:position 1");
  t.answer(":demand:acceleration 1, 40");
  CHECK(t.answer(":demand:position 1, 350") == "OK\r\n");  // 10 deg backwards
  t.advance_to(0.2);
  CHECK(t.rate_dps() < 0);
  CHECK((status_of(t) & acutrol::status_in_position) == 0);
  t.advance_to(5);
  CHECK(t.position_deg() == Approx(350.0).margin(1e-6));
  CHECK(t.rate_dps() == 0.0);
  CHECK((status_of(t) & acutrol::status_in_position) != 0);
}

// ---- the driver against the served peer ----------------------------------------------------

TEST_CASE("rate table driver against the mock peer: an acceleration-limited ramp to rate, then stop") {
  ServedTable served(RateTableSpec{});  // ripple 0.002 deg/s at 2 Hz
  RateTableConfig cfg;
  cfg.line.port = static_cast<std::uint16_t>(served.port());
  cfg.limits.max_rate_dps = 500;
  cfg.limits.max_accel_dps2 = 50;
  auto table = open_rate_table(cfg);
  REQUIRE(table);
  REQUIRE((*table)->set_rate_dps(100));
  served.sim_time_s = 1.0;
  auto s = (*table)->read_status();
  REQUIRE(s);
  CHECK(s->mode == RateTableMode::rate);
  CHECK(s->rate_dps == Approx(50.0).margin(0.003));
  CHECK(s->position_deg == Approx(25.0).margin(0.01));
  CHECK(s->moving);
  CHECK_FALSE(s->at_rate);
  served.sim_time_s = 3.125;  // a crest of the ripple: sin(2 pi 2 Hz 3.125 s) = 1
  s = (*table)->read_status();
  REQUIRE(s);
  CHECK(s->at_rate);
  CHECK(s->rate_dps == Approx(100.002).margin(1e-6));  // the ripple shows
  CHECK(s->position_deg == Approx(212.5).margin(0.001));
  REQUIRE((*table)->stop());
  served.sim_time_s = 4.125;
  s = (*table)->read_status();
  REQUIRE(s);
  CHECK(s->rate_dps == Approx(50.0).margin(0.003));
  served.sim_time_s = 6.125;
  s = (*table)->read_status();
  REQUIRE(s);
  CHECK(s->rate_dps == 0.0);
  CHECK_FALSE(s->moving);
  CHECK(s->at_rate);  // at its demand of 0
  REQUIRE((*table)->go_to_position_deg(-30));
  served.sim_time_s = 20.0;
  s = (*table)->read_status();
  REQUIRE(s);
  CHECK(s->mode == RateTableMode::position);
  CHECK(s->in_position);
  CHECK(s->position_deg == Approx(330.0).margin(1e-5));
  CHECK((*table)->take_events().empty());
}

TEST_CASE("rate table driver against the mock peer: the controller refuses a rate beyond its own limit") {
  ServedTable served(RateTableSpec{});  // the controller's limit: 1000 deg/s
  RateTableConfig cfg;
  cfg.line.port = static_cast<std::uint16_t>(served.port());
  cfg.limits.max_rate_dps = 2000;  // configured wider than the controller allows
  auto table = open_rate_table(cfg);
  REQUIRE(table);
  REQUIRE((*table)->set_rate_dps(200));
  auto r = (*table)->set_rate_dps(1500);
  REQUIRE_FALSE(r);
  CHECK(r.error().code == ErrorCode::out_of_range);
  CHECK_THAT(r.error().message, Catch::Contains("':demand:rate 1, 1500.000000' refused by the controller: "
                                                "'ERR 2: RATE LIMIT EXCEEDED, MAX 1000.000000'"));
  auto events = (*table)->take_events();
  REQUIRE(events.size() == 1);
  CHECK(events[0].kind == RateTableEvent::Kind::refused);
  CHECK_THAT(events[0].device, Catch::StartsWith("table acutrol (tcp 127.0.0.1:"));
  served.sim_time_s = 100.0;
  auto s = (*table)->read_status();
  REQUIRE(s);
  CHECK(s->rate_dps == Approx(200.0).margin(0.003));  // the refused demand changed nothing
}

TEST_CASE("rate table driver against the mock peer: a fault is reported, refuses motion and clears on reset") {
  ServedTable served(RateTableSpec{});
  RateTableConfig cfg;
  cfg.line.port = static_cast<std::uint16_t>(served.port());
  const auto at = std::chrono::system_clock::time_point(std::chrono::seconds(1795910400));
  auto table = open_rate_table(cfg, [at] { return at; });
  REQUIRE(table);
  REQUIRE((*table)->set_rate_dps(60));
  served.sim_time_s = 5.0;
  served.fault({{"name", "table_fault"}, {"text", "OVERSPEED TRIP"}});
  auto s = (*table)->read_status();
  REQUIRE(s);
  CHECK(s->fault);
  CHECK(s->fault_text == "OVERSPEED TRIP");
  CHECK(s->mode == RateTableMode::off);
  CHECK_FALSE(s->interlock_closed);
  auto events = (*table)->take_events();
  REQUIRE(events.size() == 1);
  CHECK(events[0].kind == RateTableEvent::Kind::fault);
  CHECK_THAT(events[0].to_string(), Catch::StartsWith("2026-11-29T00:00:00.000Z table acutrol (tcp 127.0.0.1:"));
  CHECK_THAT(events[0].to_string(), Catch::EndsWith("): fault: the table reports a fault: 'OVERSPEED TRIP'"));
  auto r = (*table)->set_rate_dps(60);
  REQUIRE_FALSE(r);
  CHECK(r.error().code == ErrorCode::protocol);
  CHECK_THAT(r.error().message, Catch::Contains("':mode:rate 1' refused by the controller: "
                                                "'ERR 4: FAULT ACTIVE: OVERSPEED TRIP'"));
  served.sim_time_s = 6.0;
  s = (*table)->read_status();
  REQUIRE(s);
  CHECK(s->rate_dps == 0.0);  // braked to rest
  auto acutrol_table = dynamic_cast<AcutrolRateTable*>(table->get());
  REQUIRE(acutrol_table != nullptr);
  CHECK_FALSE(acutrol_table->reset_and_close());  // the condition is still there
  served.fault({{"name", "table_fault"}, {"on", false}});
  REQUIRE(acutrol_table->reset_and_close());
  REQUIRE((*table)->set_rate_dps(60));
  s = (*table)->read_status();
  REQUIRE(s);
  CHECK_FALSE(s->fault);
  events = (*table)->take_events();
  REQUIRE(events.size() == 3);
  CHECK(events[0].kind == RateTableEvent::Kind::refused);  // the motion refused during the fault
  CHECK(events[1].kind == RateTableEvent::Kind::refused);  // the reset while it was still there
  CHECK(events[2].kind == RateTableEvent::Kind::fault_cleared);
}

TEST_CASE("rate table driver against the mock peer: a link lost mid-step is reported, and the driver reconnects") {
  ServedTable served(RateTableSpec{});
  RateTableConfig cfg;
  cfg.line.port = static_cast<std::uint16_t>(served.port());
  cfg.line.backoff.initial_ms = 1000;
  auto now = std::chrono::steady_clock::now();
  auto table = open_rate_table(cfg, {}, [&now] { return now; });
  REQUIRE(table);
  REQUIRE((*table)->set_rate_dps(100));
  served.sim_time_s = 10.0;
  served.fault({{"name", "drop_table"}});
  REQUIRE(served.wait_no_clients());
  auto s = (*table)->read_status();
  REQUIRE_FALSE(s);
  CHECK(s.error().code == ErrorCode::connection);
  CHECK_THAT(s.error().message, Catch::Contains("':read:status 1'"));
  auto events = (*table)->take_events();
  REQUIRE(events.size() == 1);
  CHECK(events[0].kind == RateTableEvent::Kind::link_lost);
  CHECK_THAT(events[0].reason, Catch::StartsWith("link lost: ':read:status 1': "));
  // Within the backoff: refused at once, and no second event.
  s = (*table)->read_status();
  REQUIRE_FALSE(s);
  CHECK_THAT(s.error().message, Catch::Contains("before the next connection attempt"));
  CHECK((*table)->take_events().empty());
  now += std::chrono::seconds(2);
  s = (*table)->read_status();
  REQUIRE(s);
  CHECK(s->at_rate);  // the table kept its rate through the link loss
  CHECK(s->rate_dps == Approx(100.0).margin(0.003));
  events = (*table)->take_events();
  REQUIRE(events.size() == 1);
  CHECK(events[0].kind == RateTableEvent::Kind::link_restored);
  // The driver says its mode again on the new connection.
  REQUIRE((*table)->set_rate_dps(-50));
  served.sim_time_s = 20.0;
  s = (*table)->read_status();
  REQUIRE(s);
  CHECK(s->rate_dps == Approx(-50.0).margin(0.003));
}
