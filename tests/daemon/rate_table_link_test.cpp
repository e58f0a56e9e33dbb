// The daemon's link to the rate table (rate_table_link.hpp) with a scripted table: a status read
// that fails for a reason other than the link (a garbled reply) is tolerated up to
// rate_table.status_tolerance reads in a row, then the reading says `unreadable` naming the count
// and the last reply; a good read starts the count again; the station aborts a run on it. No
// I/O, no sleeps: each second's job is awaited by running the loop until its result is posted.
#include "fixture.hpp"

#include <boost/asio.hpp>
#include <deque>
#include <filesystem>
#include <fstream>
#include <unistd.h>

#include "../../daemon/src/rate_table_link.hpp"

using namespace fogbench;
using namespace fogbench::daemon;
using namespace fogbench::daemon::test;

namespace {

// Answers each status read from a script: a reply text the driver could not read (a protocol
// error quoting it), or "" for a good status.
class ScriptedTable : public drivers::RateTable {
 public:
  explicit ScriptedTable(std::deque<std::string> script) : script_(std::move(script)) {}
  drivers::Result<void> set_rate_dps(double) override { return {}; }
  drivers::Result<void> go_to_position_deg(double) override { return {}; }
  drivers::Result<void> stop() override { return {}; }
  drivers::Result<drivers::RateTableStatus> read_status() override {
    std::string next;
    if (!script_.empty()) {
      next = script_.front();
      script_.pop_front();
    }
    if (next.empty()) return drivers::RateTableStatus{};
    return drivers::fail(drivers::ErrorCode::protocol,
                         "table acutrol (tcp 127.0.0.1:9888): ':read:status? 1' answered '" + next + "', not a status word 0..65535");
  }
  const drivers::RateTableLimits& limits() const noexcept override { return limits_; }
  std::vector<drivers::RateTableEvent> take_events() override { return {}; }

 private:
  std::deque<std::string> script_;
  drivers::RateTableLimits limits_;
};

struct LinkRig {
  boost::asio::io_context loop;
  boost::asio::executor_work_guard<boost::asio::io_context::executor_type> keep{loop.get_executor()};
  RateTableLink link;
  LinkRig(std::deque<std::string> script, int tolerance)
      : link(loop, std::make_unique<ScriptedTable>(std::move(script)), tolerance) {}
  // One second: the command and status read on the worker, its result taken on the loop.
  RateTableReading second(double rate_dps = 10.0) {
    link.command(rate_dps);
    loop.run_one();  // blocks until the worker posts the job's result
    return link.reading();
  }
};

}  // namespace

TEST_CASE("rate table link: failed status reads are tolerated up to status_tolerance in a row, then unreadable naming the last reply") {
  LinkRig r({"", "#@!1", "#@!2", "", "#@!3", "#@!4", "#@!5"}, 3);
  CHECK(r.second().reason.empty());
  // Two failed reads: each says why, none aborts.
  for (int k = 1; k <= 2; ++k) {
    const auto rd = r.second();
    INFO(rd.reason);
    CHECK_FALSE(rd.unreadable);
    CHECK_FALSE(rd.link_down);
    CHECK_FALSE(rd.fault);
    CHECK_THAT(rd.reason, Catch::Contains("status not read") && Catch::Contains("#@!" + std::to_string(k)));
  }
  // A good read starts the count again.
  const auto good = r.second();
  CHECK_FALSE(good.unreadable);
  CHECK(good.reason.empty());
  CHECK_FALSE(r.second().unreadable);  // 1 in a row
  CHECK_FALSE(r.second().unreadable);  // 2
  const auto bad = r.second();         // 3: the tolerance
  INFO(bad.reason);
  CHECK(bad.unreadable);
  CHECK_FALSE(bad.link_down);
  CHECK_THAT(bad.reason, Catch::Contains("3 status reads in a row failed (rate_table.status_tolerance 3)") &&
                             Catch::Contains("answered '#@!5'"));
}

TEST_CASE("rate table link: a tolerance of 1 makes the first failed status read unreadable") {
  LinkRig r({"garbled"}, 1);
  const auto rd = r.second();
  CHECK(rd.unreadable);
  CHECK_THAT(rd.reason, Catch::Contains("answered 'garbled'"));
}

TEST_CASE("station rate table: a status unreadable aborts the run naming the table and the reason, 0 deg/s commanded") {
  const auto dir = std::filesystem::temp_directory_path() / ("fogbench-rate-link-" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  std::ofstream(dir / "spin.profile") << "setpoint 20 C\nhold 8 s\nrate 10 dps for 8 s\n";
  storage::Store store = memory_store();
  auto c = golden_config({{"profile_dir", dir.string()},
                          {"rate_table", {{"kind", "acutrol"}, {"link", {{"transport", "tcp"}, {"host", "127.0.0.1"}, {"port", 9888}}}}}});
  Station st(std::move(c), store, 1.0, [] { return std::string("2026-01-01T00:00:00Z"); });
  auto run = st.start_run("spin", {"FOG-0001"}, storage::Purpose::fit, {{"cmd", "run.start"}});
  REQUIRE(run.has_value());
  SyntheticBench bench{1};
  double sp = 20.0;
  auto tick = [&](double t, RateTableReading table) {
    TickInput in = bench.step(sp);
    in.rate_table = table;
    const auto out = st.tick(t, in);
    sp = out.setpoint_c;
    return out;
  };
  CHECK(tick(0, {}).rate_dps == 10.0);
  // Below the tolerance the reading carries only a reason: the run goes on.
  RateTableReading once;
  once.reason = "status not read: protocol: ... answered '#@!'";
  CHECK(tick(1, once).rate_dps == 10.0);
  RateTableReading unreadable;
  unreadable.unreadable = true;
  unreadable.reason = "5 status reads in a row failed (rate_table.status_tolerance 5); the last: answered '#@!'";
  CHECK(tick(2, unreadable).rate_dps == 0.0);
  auto rec = store.get_run(*run);
  REQUIRE(rec.has_value());
  CHECK(rec->run.state == storage::RunState::aborted);
  CHECK_THAT(rec->run.state_reason, Catch::Contains("rate table status unreadable: 5 status reads in a row failed") &&
                                        Catch::Contains("answered '#@!'"));
  std::error_code ec;
  std::filesystem::remove_all(dir, ec);
}

TEST_CASE("config: rate_table.status_tolerance is read by the daemon, its bad values named") {
  auto base = [](nlohmann::json tol) {
    nlohmann::json j = golden_config_json();
    j["rate_table"] = {{"kind", "acutrol"}, {"link", {{"transport", "tcp"}, {"host", "127.0.0.1"}, {"port", 9888}}}};
    if (!tol.is_null()) j["rate_table"]["status_tolerance"] = tol;
    return parse_daemon_config(j, golden_dir());
  };
  auto d = base(nullptr);
  REQUIRE(d.has_value());
  CHECK(d->rate_table_status_tolerance == 5);
  auto t = base(12);
  REQUIRE(t.has_value());
  CHECK(t->rate_table_status_tolerance == 12);
  REQUIRE(t->rate_table.has_value());
  for (auto bad : {nlohmann::json(0), nlohmann::json(3601), nlohmann::json("5"), nlohmann::json(2.5)}) {
    auto e = base(bad);
    REQUIRE_FALSE(e.has_value());
    CHECK_THAT(e.error(), Catch::Contains("rate_table.status_tolerance: expected an integer 1..3600"));
  }
}
