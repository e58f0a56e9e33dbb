// The station driving a rate table (issue 29): each second's commanded rate from the profile's
// rate steps, stored with every row and handed back to the server (TickOutput::rate_dps); a fault
// or a lost link of the table ends the run aborted and commands 0 deg/s. Without I/O.
#include "fixture.hpp"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <unistd.h>

#include "fogbench/storage/csv.hpp"

using namespace fogbench;
using namespace fogbench::daemon;
using namespace fogbench::daemon::test;
using nlohmann::json;

namespace {

struct Rig {
  std::filesystem::path dir;
  storage::Store store = memory_store();
  std::unique_ptr<Station> st;
  SyntheticBench bench{1};
  double clock_s = 0.0;
  double sp_c = 20.0;
  std::int64_t run = 0;

  Rig() {
    dir = std::filesystem::temp_directory_path() / ("fogbench-rate-" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir);
    std::ofstream(dir / "spin.profile") << "setpoint 20 C\nhold 8 s\nrate 10 dps for 2 s\nrate -10 dps for 3 s\n";
    auto c = golden_config({{"profile_dir", dir.string()},
                            {"rate_table", {{"kind", "acutrol"}, {"link", {{"transport", "tcp"}, {"host", "127.0.0.1"}, {"port", 9888}}}}}});
    st = std::make_unique<Station>(std::move(c), store, 1.0, [] { return std::string("2026-01-01T00:00:00Z"); });
    auto id = st->start_run("spin", {"FOG-0001"}, storage::Purpose::fit, {{"cmd", "run.start"}});
    INFO((id ? std::string() : id.error().message));
    REQUIRE(id.has_value());
    run = *id;
  }
  ~Rig() {
    std::error_code ec;
    std::filesystem::remove_all(dir, ec);
  }
  TickOutput tick(RateTableReading table = {}) {
    TickInput in = bench.step(sp_c);
    in.rate_table = table;
    const TickOutput out = st->tick(clock_s, in);
    sp_c = out.setpoint_c;
    clock_s += 1.0;
    return out;
  }
};

}  // namespace

TEST_CASE("station rate table: each second commands and stores the plateau's rate, 0 after the sequence") {
  Rig r;
  std::vector<double> commanded;
  for (int k = 0; k < 12; ++k) commanded.push_back(r.tick().rate_dps);
  // 0..7 the hold (10, 10, -10 x3, 0 x3), then the run completes: 0 from then on.
  const std::vector<double> want = {10, 10, -10, -10, -10, 0, 0, 0, 0, 0, 0, 0};
  CHECK(commanded == want);
  auto rec = r.store.get_run(r.run);
  REQUIRE(rec.has_value());
  CHECK(rec->run.state == storage::RunState::completed);
  auto d = r.store.export_run(r.run, 0, {});
  REQUIRE(d.has_value());
  REQUIRE(d->has_rate_in());
  REQUIRE(d->size() >= 8);
  for (std::size_t i = 0; i < 8; ++i) {
    INFO("t_s " << d->time_s[i]);
    CHECK(d->rate_in_dps[i] == want[static_cast<std::size_t>(d->time_s[i])]);
  }
  // The CSV carries the rate-sequence columns fogctl scale-factor reads.
  const std::string csv = storage::to_csv(*d);
  CHECK(csv.substr(0, csv.find('\n')).find(",plateau,rate_in_dps,rate_out_dps") != std::string::npos);
}

TEST_CASE("station rate table: a fault the table reports aborts the run naming it, and the table is commanded to 0") {
  Rig r;
  CHECK(r.tick().rate_dps == 10.0);
  RateTableReading fault;
  fault.fault = true;
  fault.reason = "OVERSPEED TRIP";
  CHECK(r.tick(fault).rate_dps == 0.0);
  auto rec = r.store.get_run(r.run);
  REQUIRE(rec.has_value());
  CHECK(rec->run.state == storage::RunState::aborted);
  CHECK_THAT(rec->run.state_reason, Catch::Contains("rate table fault: OVERSPEED TRIP"));
  CHECK(r.tick().rate_dps == 0.0);
}

TEST_CASE("station rate table: the table's link lost aborts the run") {
  Rig r;
  r.tick();
  RateTableReading lost;
  lost.link_down = true;
  lost.reason = "timeout: table acutrol (tcp 127.0.0.1:9888): no reply";
  CHECK(r.tick(lost).rate_dps == 0.0);
  auto rec = r.store.get_run(r.run);
  REQUIRE(rec.has_value());
  CHECK(rec->run.state == storage::RunState::aborted);
  CHECK_THAT(rec->run.state_reason, Catch::Contains("rate table link lost: timeout"));
}

TEST_CASE("station rate table: a table rate beyond what a unit's counts carry at its scale is refused by line and unit") {
  const auto dir = std::filesystem::temp_directory_path() / ("fogbench-rate-scale-" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  // 60 deg/s is within the table's default limit but beyond the golden units' +-59.65 deg/s
  // (int32 counts at 1e-4 deg/h per count).
  std::ofstream(dir / "fast.profile") << "setpoint 20 C\nhold 8 s\nrate 10 dps for 2 s\nrate 60 dps for 2 s\n";
  std::ofstream(dir / "slow.profile") << "setpoint 20 C\nhold 8 s\nrate 59 dps for 2 s\n";
  storage::Store store = memory_store();
  Station st(golden_config({{"profile_dir", dir.string()},
                            {"rate_table", {{"kind", "acutrol"}, {"link", {{"transport", "tcp"}, {"host", "127.0.0.1"}, {"port", 9888}}}}}}),
             store, 1.0, [] { return std::string("2026-01-01T00:00:00Z"); });
  auto refused = st.start_run("fast", {"FOG-0001"}, storage::Purpose::fit, {{"cmd", "run.start"}});
  REQUIRE_FALSE(refused.has_value());
  CHECK(refused.error().code == ErrorCode::limits);
  const std::string& why = refused.error().message;
  INFO(why);
  CHECK(why.find("fast.profile:4:") != std::string::npos);
  CHECK(why.find("units[0]") != std::string::npos);
  CHECK(why.find("59.65") != std::string::npos);
  auto runs = store.list_runs();
  REQUIRE(runs.has_value());
  CHECK(runs->empty());
  // Within every unit's range: accepted.
  auto ok = st.start_run("slow", {"FOG-0001"}, storage::Purpose::fit, {{"cmd", "run.start"}});
  INFO((ok ? std::string() : ok.error().message));
  CHECK(ok.has_value());
  std::error_code ec;
  std::filesystem::remove_all(dir, ec);
}
