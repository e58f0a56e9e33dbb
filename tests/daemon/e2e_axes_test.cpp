// Three-axis units live (issue 29 point 3): fogbench-sim --axes 3 and the real fogbenchd on the
// paced clock; the stored run has every axis of every unit: run.samples pages gyro_y_dph and
// gyro_z_dph, each axis's mean offset from x is the bias the mock gave it, and the store file
// holds the units as three-axis (their export has the y and z columns).
#include "live_bench.hpp"

#include <cmath>

#include "fogbench/storage/csv.hpp"
#include "fogbench/storage/runs.hpp"
#include "fogbench/storage/samples.hpp"
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

namespace {
double elapsed_of(const json& status) {
  return status["run"].is_object() && status["run"]["elapsed_s"].is_number() ? status["run"]["elapsed_s"].get<double>() : -1.0;
}
}  // namespace

TEST_CASE("e2e axes: the mock silences axis z of one unit mid-run, the daemon flags it and x, y and the other unit flow on") {
  require_sim();
  LiveBench bench(100.0, json::object(), true, nullptr, {"--axes", "3", "--axis-bias-dph", "20"});
  INFO("test dir " << bench.dir);
  LineClient c(bench.socket());
  REQUIRE(c.ok());
  const auto run = bench.start_run(c, "short", {"SIM-0001", "SIM-0002"});
  auto s = bench.wait_status(c, [](const json& r) { return elapsed_of(r) >= 30.0; }, 120s);
  const double before_s = elapsed_of(s["result"]);
  REQUIRE(before_s >= 30.0);

  // Axis z of SIM-0001 stops sending: the bench lists the fault.
  auto on = bench.sim_command({{"cmd", "fault"}, {"name", "silence_axis"}, {"unit", "SIM-0001"}, {"axis", "z"}});
  INFO(on.dump());
  REQUIRE(on["ok"] == true);
  auto st = bench.sim_command({{"cmd", "status"}});
  bool listed = false;
  for (const auto& f : st["faults"]) listed = listed || (f["name"] == "silence_axis" && f["axis"] == "z" && f["unit"] == 0);
  CHECK(listed);
  s = bench.wait_status(c, [&](const json& r) { return elapsed_of(r) >= before_s + 40.0; }, 120s);
  const double off_s = elapsed_of(s["result"]);
  REQUIRE(off_s >= before_s + 40.0);
  REQUIRE(bench.sim_command({{"cmd", "fault"}, {"name", "silence_axis"}, {"unit", 0}, {"on", false}})["ok"] == true);
  bench.wait_status(c, [&](const json& r) { return elapsed_of(r) >= off_s + 20.0; }, 120s);
  REQUIRE(code_of(c.call({{"cmd", "run.abort"}, {"reason", "e2e axes: silence seen"}})) == "ok");
  json done = bench.wait_state(c, run, {"aborted"}, 60s);
  REQUIRE(done.contains("result"));

  // One fault event naming the device (unit, serial, axis, CAN id), the time and the reason,
  // at a second after the fault was given and before it was lifted.
  std::vector<json> silent;
  double silent_t_s = -1.0;
  for (const auto& e : done["result"]["events"])
    if (e["kind"] == "fault" && e["detail"].is_object() && e["detail"].value("gyro_axis", "") == "silent") {
      silent.push_back(e["detail"]);
      silent_t_s = e["t_s"].get<double>();
    }
  INFO(done["result"]["events"].dump());
  REQUIRE(silent.size() == 1);
  const json& ev = silent[0];
  CHECK(ev["unit"] == 0);
  CHECK(ev["serial"] == "SIM-0001");
  CHECK(ev["axis"] == "z");
  CHECK(ev["can_id"] == bench.ready_sim["drivers_config"]["units"][0]["gyro"]["node_id"].get<int>() + 2);
  CHECK(ev["t_s"].get<double>() == silent_t_s);
  CHECK(silent_t_s >= before_s);
  CHECK(silent_t_s <= before_s + 10.0);  // the fault acts on the next frames: within a few seconds
  CHECK_THAT(ev["reason"].get<std::string>(), Catch::Contains("no frame on CAN id"));

  // The stored seconds: while z is silent, unit 0's x and y have their values and z none (the
  // second flagged missing); the other unit's three axes go on; z is back once switched on.
  auto rows_of = [&](int unit) {
    auto page = c.call({{"cmd", "run.samples"}, {"run_id", run}, {"unit", unit}, {"offset", 0}, {"limit", 10000}});
    REQUIRE(code_of(page) == "ok");
    return page["result"]["samples"];
  };
  const json rows0 = rows_of(0), rows1 = rows_of(1);
  int silent_rows = 0, back_rows = 0, other_rows = 0;
  for (const auto& r : rows0) {
    const double t = r["t_s"].get<double>();
    if (t >= silent_t_s + 1.0 && t < off_s - 1.0) {
      ++silent_rows;
      CHECK(r["gyro_dph"].is_number());
      CHECK(r["gyro_y_dph"].is_number());
      CHECK(r["gyro_z_dph"].is_null());
      CHECK((r["flags"].get<int>() & 1) != 0);
    } else if (t >= off_s + 5.0) {
      ++back_rows;
      CHECK(r["gyro_z_dph"].is_number());
    }
  }
  for (const auto& r : rows1) {
    const double t = r["t_s"].get<double>();
    if (t < silent_t_s + 1.0 || t >= off_s - 1.0) continue;
    ++other_rows;
    CHECK(r["gyro_dph"].is_number());
    CHECK(r["gyro_y_dph"].is_number());
    CHECK(r["gyro_z_dph"].is_number());
    CHECK((r["flags"].get<int>() & 1) == 0);
  }
  CHECK(silent_rows >= 30);
  CHECK(other_rows == silent_rows);
  CHECK(back_rows >= 10);
}
