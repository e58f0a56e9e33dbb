// What every reader of a stored run shares (run_data.hpp): gap bridging and the ISO time (the
// stored phase is checked through the daemon's and fogctl's runs).
#include <catch2/catch.hpp>

#include <cmath>

#include "fogbench/storage/run_data.hpp"

using namespace fogbench;

TEST_CASE("run data: a value not read takes the last one read before it and its sample is flagged missing") {
  model::RunData d;
  const double nan = std::nan("");
  d.time_s = {0, 1, 2, 3};
  d.gyro_dph = {nan, 1.0, nan, 3.0};  // a leading gap takes the first value read
  d.t1_c = {20, 20, 20, 20};
  d.t2_c = {20, 20, 20, 20};
  d.setpoint_c = {20, 20, 20, 20};
  d.chamber_c = {20, nan, nan, 21};
  d.flags = {0, 0, 0, 4};
  storage::bridge_missing(d);
  CHECK(d.gyro_dph == std::vector<double>{1.0, 1.0, 1.0, 3.0});
  CHECK(d.chamber_c == std::vector<double>{20, 20, 20, 21});
  CHECK(d.flags[0] == model::flag::missing);
  CHECK(d.flags[1] == model::flag::missing);
  CHECK(d.flags[2] == model::flag::missing);
  CHECK(d.flags[3] == 4);  // read in full: its own flags kept, missing not added
}

TEST_CASE("run data: ISO 8601 UTC, to the second or the millisecond, floored before 1970") {
  using namespace std::chrono;
  // 1795298101.924 s = 2026-11-21T21:55:01.924Z (the example of docs/protocol.md's run.list).
  const system_clock::time_point t{milliseconds(1795298101924)};
  CHECK(storage::iso8601_utc(t) == "2026-11-21T21:55:01Z");
  CHECK(storage::iso8601_utc(t, true) == "2026-11-21T21:55:01.924Z");
  const system_clock::time_point before{milliseconds(-1)};
  CHECK(storage::iso8601_utc(before, true) == "1969-12-31T23:59:59.999Z");
}
