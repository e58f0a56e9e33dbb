// Time in milliseconds: read with CsvOptions::time_scale (fogctl --time-unit ms), and refused
// when resampled as if it were seconds (fogctl's old hint, --resample 1, had made a 5400 s run
// in ms into 5.4 M interpolated rows).
#include <catch2/catch.hpp>
#include <string>

#include "fogbench/storage/csv.hpp"

using namespace fogbench;
using Catch::Contains;

namespace {
// n samples 1 s apart, written in ms.
std::string in_ms(int n) {
  std::string s = "time_s,gyro_dph,t1_c,t2_c\n";
  for (int i = 0; i < n; ++i) s += std::to_string(i * 1000) + ",-8,20,20\n";
  return s;
}
}  // namespace

TEST_CASE("csv: time in ms read with time_scale 1e-3 is 1 s apart", "[csv]") {
  storage::CsvOptions o;
  o.time_scale = 1e-3;
  auto r = storage::parse_csv(in_ms(10), o);
  REQUIRE(r);
  CHECK(r->size() == 10);
  CHECK(r->time_s[9] == Approx(9.0));
  o.time_scale = 0;
  auto bad = storage::parse_csv(in_ms(10), o);
  REQUIRE_FALSE(bad);
  CHECK(bad.error().code == storage::CsvErrc::bad_option);
}

TEST_CASE("csv: resampling time in ms every 1 s is refused with the unit named", "[csv]") {
  storage::CsvOptions o;
  o.resample_s = 1.0;
  auto r = storage::parse_csv(in_ms(10), o);
  REQUIRE_FALSE(r);
  CHECK(r.error().code == storage::CsvErrc::bad_option);
  // 1000 per sample resampled every 1 s: 999 of every 1000 rows invented.
  CHECK_THAT(r.error().message, Contains("999 of every 1000") && Contains("--time-unit ms"));
  // Resampling ten times finer than the recording is still allowed (a 10 s logger read at 1 s).
  std::string ten = "time_s,gyro_dph,t1_c,t2_c\n";
  for (int i = 0; i < 10; ++i) ten += std::to_string(i * 10) + ",-8,20,20\n";
  auto ok = storage::parse_csv(ten, o);
  REQUIRE(ok);
  CHECK(ok->size() == 91);
}
