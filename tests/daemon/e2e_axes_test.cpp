// Three-axis units live (issue 29 point 3): fogbench-sim --axes 3 and the real fogbenchd on the
// paced clock; the stored run has every axis of every unit: run.samples pages gyro_y_dph and
// gyro_z_dph, each axis's mean offset from x is the bias the mock gave it, and the store file
// holds the units as three-axis (their export has the y and z columns).
#include "live_bench.hpp"

#include <cmath>

#include "fogbench/storage/csv.hpp"
#include "fogbench/storage/store.hpp"

using namespace fogbench;
using namespace fogbench::daemon::test;
using namespace fogbench::daemon::test::live;
using nlohmann::json;
using namespace std::chrono_literals;

TEST_CASE("e2e axes: a run of three-axis units from fogbench-sim --axes 3 stores x, y and z of every second") {
  require_sim();
  LiveBench bench(100.0, json::object(), true, nullptr, {"--axes", "3", "--axis-bias-dph", "20"});
  INFO("test dir " << bench.dir);
  REQUIRE(bench.ready_sim["drivers_config"]["units"][0]["gyro"]["axes"] == 3);
  LineClient c(bench.socket());
  REQUIRE(c.ok());
  const auto run = bench.start_run(c, "short", {"SIM-0001", "SIM-0002"});

  // 120 s of run time is enough to see every axis; the run is then aborted.
  bench.wait_status(c, [](const json& r) {
    return r["run"].is_object() && r["run"]["elapsed_s"].is_number() && r["run"]["elapsed_s"].get<double>() >= 120.0;
  }, 180s);
  auto ab = c.call({{"cmd", "run.abort"}, {"reason", "e2e axes: enough seconds"}});
  REQUIRE(code_of(ab) == "ok");
  json done = bench.wait_state(c, run, {"aborted"}, 60s);
  REQUIRE(done.contains("result"));

  for (int unit = 0; unit < 2; ++unit) {
    INFO("unit " << unit);
    auto page = c.call({{"cmd", "run.samples"}, {"run_id", run}, {"unit", unit}, {"offset", 0}, {"limit", 10000}});
    REQUIRE(code_of(page) == "ok");
    const auto& rows = page["result"]["samples"];
    REQUIRE(rows.size() >= 120);
    const json bias = bench.ready_sim["units"][static_cast<std::size_t>(unit)]["axis_bias_dph"];
    REQUIRE(bias.size() == 3);
    double dy = 0, dz = 0;
    std::size_t n = 0;
    for (const auto& r : rows) {
      REQUIRE(r.contains("gyro_y_dph"));
      REQUIRE(r.contains("gyro_z_dph"));
      if ((r["flags"].get<int>() & 1) != 0) continue;  // a second flagged missing
      REQUIRE(r["gyro_dph"].is_number());
      REQUIRE(r["gyro_y_dph"].is_number());
      REQUIRE(r["gyro_z_dph"].is_number());
      dy += r["gyro_y_dph"].get<double>() - r["gyro_dph"].get<double>();
      dz += r["gyro_z_dph"].get<double>() - r["gyro_dph"].get<double>();
      ++n;
    }
    // The first seconds may miss an axis (frames of a second split at the start); the rest not.
    REQUIRE(n + 5 >= rows.size());
    // y - x and z - x: the axis's own bias plus the difference of two noises (deg/h, small
    // beside the 20 deg/h sigma of the biases): each axis is read from its own CAN id.
    CHECK(dy / static_cast<double>(n) == Approx(bias[1].get<double>()).margin(0.5));
    CHECK(dz / static_cast<double>(n) == Approx(bias[2].get<double>()).margin(0.5));
  }

  // The store file: the units three-axis, their export with the y and z columns.
  bench.daemon.reset();
  auto store = storage::Store::open(bench.dir / "fogbench.db");
  REQUIRE(store.has_value());
  auto d = store->get_run(run);
  REQUIRE(d.has_value());
  REQUIRE(d->run.units.size() == 2);
  CHECK(d->run.units[0].axes == 3);
  CHECK(d->run.units[1].axes == 3);
  auto x = store->export_run(run, 0, {.include_settle = true});
  REQUIRE(x.has_value());
  CHECK(x->has_axes());
  CHECK(storage::to_csv(*x).starts_with("time_s,gyro_dph,t1_c,t2_c,"));
  CHECK(storage::to_csv(*x).find(",gyro_y_dph,gyro_z_dph\n") != std::string::npos);
}
