// The samples' binary COPY at its edges (plant/src/copy_binary.hpp, sample_stream.hpp), against a
// real PostgreSQL started by the test: a unit whose samples fill whole pages exactly (the last
// page read is empty and carries only the trailer), a unit without samples, every column's
// extreme values and NULLs, byte for byte as the bench stored them.
#include <catch2/catch.hpp>

#include <cmath>
#include <limits>

#include "bench_run.hpp"
#include "fogbench/plant/plant.hpp"
#include "pg_server.hpp"

using namespace fogbench;

TEST_CASE("binary COPY: whole pages, a unit without samples, extreme values and NULLs arrive exactly") {
  test::PgServer pg;
  const auto path = test::temp_store_path("binary");
  auto opened = storage::Store::open(path);
  REQUIRE(opened);
  storage::Store& bench = *opened;
  storage::NewRun nr;
  nr.profile_name = "edges";
  nr.unit_serials = {"FOG-0001", "FOG-0002", "FOG-0003"};
  nr.unit_axes = {1, 1, 3};  // unit 2 has three axes: its y and z travel too (schema 5)
  auto id = bench.create_run(nr);
  REQUIRE(id);
  REQUIRE(bench.set_run_state(*id, storage::RunState::running, "go"));
  // Unit 0: exactly two pages of 50,000 rows; unit 1: none; unit 2: three rows at the edges.
  std::vector<storage::SampleRow> rows;
  for (int i = 0; i < 100000; ++i) {
    storage::SampleRow r;
    r.unit_index = 0;
    r.t_s = i;
    r.gyro_dph = 0.001 * i - 17.25;
    r.frames = i;
    r.step = i % 7;
    r.phase = model::Phase::heating;
    r.flags = static_cast<std::uint8_t>(i % 3);
    rows.push_back(r);
  }
  storage::SampleRow lo, hi, none;
  lo.unit_index = hi.unit_index = none.unit_index = 2;
  lo.t_s = 0.5;
  lo.gyro_dph = -std::numeric_limits<double>::max();
  lo.t1_c = std::numeric_limits<double>::denorm_min();
  lo.frames = std::numeric_limits<std::int64_t>::min();
  lo.step = std::numeric_limits<int>::min();
  lo.flags = 255;
  lo.phase = model::Phase::cooling;
  hi.t_s = 1e15;
  hi.gyro_dph = std::numeric_limits<double>::max();
  hi.t1_c = 123456.789;
  hi.frames = std::numeric_limits<std::int64_t>::max();
  hi.step = std::numeric_limits<int>::max();
  hi.since_power_on_s = 1.0 / 3.0;
  hi.compensated_dph = -1e-300;
  hi.rate_in_dps = -123.5;  // the rate table's commanded rate, deg/s
  hi.gyro_y_dph = std::numeric_limits<double>::min();
  hi.gyro_z_dph = -0.1;
  hi.t1_y_c = 25.125;  // a three-axis unit's per-axis coil thermistors, degC
  hi.t2_y_c = -40.5;
  hi.t1_z_c = std::numeric_limits<double>::denorm_min();
  hi.t2_z_c = 1e300;
  none.t_s = 0.25;  // every optional signal left out: NULL
  rows.push_back(lo);
  rows.push_back(hi);
  rows.push_back(none);
  REQUIRE(bench.append_samples(*id, rows));
  REQUIRE(bench.set_run_state(*id, storage::RunState::completed, "done"));

  auto c = plant::Connection::open(pg.conninfo(), true);
  REQUIRE(c);
  auto st = plant::replicate_run(*c, bench, "bench-bin", *id);
  REQUIRE(st);
  CHECK(st->samples == 100003);
  CHECK(pg.psql("SELECT string_agg(unit_index || ':' || n, ',' ORDER BY unit_index) FROM (SELECT unit_index, "
                "count(*) n FROM fogbench.samples GROUP BY unit_index) s") == "0:100000,2:3");
  CHECK(pg.psql("SELECT count(*) FROM fogbench.samples WHERE unit_index = 0 AND (gyro_dph <> t_s * 0.001 - 17.25 "
                "AND abs(gyro_dph - (t_s * 0.001 - 17.25)) > 1e-9 OR frames <> t_s OR step <> t_s::bigint % 7 OR "
                "phase <> " +
                std::to_string(static_cast<int>(model::Phase::heating)) + " OR flags <> t_s::bigint % 3)") == "0");
  // Doubles exactly (PostgreSQL prints the shortest text that reads back the same), integers at
  // their limits.
  auto edge = [&](double t) {
    return pg.psql("SELECT concat_ws(' ', gyro_dph, t1_c, frames, step, flags, phase, "
                   "coalesce(since_power_on_s::text, 'null'), coalesce(compensated_dph::text, 'null'), "
                   "coalesce(wall_time::text, 'null')) FROM fogbench.samples WHERE unit_index = 2 AND t_s = " +
                   std::to_string(t));
  };
  CHECK(edge(0.5) == "-1.7976931348623157e+308 5e-324 -9223372036854775808 -2147483648 255 " +
                          std::to_string(static_cast<int>(model::Phase::cooling)) + " null null null");
  CHECK(edge(1e15) == "1.7976931348623157e+308 123456.789 9223372036854775807 2147483647 0 " +
                          std::to_string(static_cast<int>(model::Phase::unknown)) +
                          " 0.3333333333333333 -1e-300 null");
  // The table's rate and the y and z axes: exact where the bench had them, NULL elsewhere.
  auto axes = [&](double t) {
    return pg.psql("SELECT concat_ws(' ', coalesce(rate_in_dps::text, 'null'), coalesce(gyro_y_dph::text, 'null'), "
                   "coalesce(gyro_z_dph::text, 'null')) FROM fogbench.samples WHERE unit_index = 2 AND t_s = " +
                   std::to_string(t));
  };
  CHECK(axes(1e15) == "-123.5 2.2250738585072014e-308 -0.1");
  CHECK(axes(0.5) == "null null null");
  // The per-axis coil thermistors (the bench's schema 15): exact where recorded, NULL elsewhere.
  auto coils = [&](double t) {
    return pg.psql("SELECT concat_ws(' ', coalesce(t1_y_c::text, 'null'), coalesce(t2_y_c::text, 'null'), "
                   "coalesce(t1_z_c::text, 'null'), coalesce(t2_z_c::text, 'null')) FROM fogbench.samples "
                   "WHERE unit_index = 2 AND t_s = " + std::to_string(t));
  };
  CHECK(coils(1e15) == "25.125 -40.5 5e-324 1e+300");
  CHECK(coils(0.5) == "null null null null");
  CHECK(pg.psql("SELECT count(rate_in_dps) + count(gyro_y_dph) + count(gyro_z_dph) FROM fogbench.samples WHERE unit_index = 0") == "0");
  CHECK(pg.psql("SELECT string_agg(unit_index || ':' || axes, ',' ORDER BY unit_index) FROM fogbench.units") == "0:1,1:1,2:3");
  CHECK(pg.psql("SELECT concat_ws(' ', coalesce(gyro_dph::text, 'null'), coalesce(frames::text, 'null'), "
                "coalesce(step::text, 'null'), coalesce(t1_c::text, 'null')) FROM fogbench.samples WHERE t_s = 0.25") ==
        "null null null null");
  std::filesystem::remove(path);
}
