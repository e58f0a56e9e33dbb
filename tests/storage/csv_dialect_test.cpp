// CSV of other dialects (issue 15): ';' or tab between fields, decimal commas, headers in any
// case, every missing column named at once; line numbers in errors are the file's.
#include <catch2/catch.hpp>

#include "fogbench/storage/csv.hpp"

using namespace fogbench::storage;
using Catch::Contains;

namespace {
CsvError error_of(const std::string& text, const CsvOptions& o = {}) {
  auto r = parse_csv(text, o);
  REQUIRE_FALSE(r);
  return r.error();
}
}  // namespace

TEST_CASE("csv dialect: semicolons detected, decimal commas read as the same doubles as decimal points", "[csv]") {
  CsvOptions o;
  o.decimal_comma = true;
  auto r = parse_csv("time_s;gyro_dph;t1_c;t2_c\n0;1,25;-0,5;20\n1;1,5;-0,25;20,125\n", o);
  INFO((r ? "" : r.error().message));
  REQUIRE(r);
  REQUIRE(r->size() == 2);
  CHECK(r->gyro_dph[0] == 1.25);  // exact: 1.25 is a binary fraction, as are the others
  CHECK(r->t1_c[0] == -0.5);
  CHECK(r->t2_c[1] == 20.125);
}

TEST_CASE("csv dialect: tab detected, headers in any case, an exact name winning over another case", "[csv]") {
  auto r = parse_csv("TIME_S\tGyro_dph\tt1_C\tT2_c\tchamber_c\n0\t1\t2\t3\t4\n1\t1\t2\t3\t4\n", {});
  INFO((r ? "" : r.error().message));
  REQUIRE(r);
  CHECK(r->t2_c[1] == 3.0);
  CHECK(r->chamber_c[0] == 4.0);
  auto e = parse_csv("time_s,Gyro_DPH,gyro_dph,t1_c,t2_c\n0,9,1,2,3\n1,9,1,2,3\n", {});
  REQUIRE(e);
  CHECK(e->gyro_dph[0] == 1.0);
}

TEST_CASE("csv dialect: a quoted header name with a comma in a semicolon file stays one column", "[csv]") {
  CsvOptions o;
  o.column_map = {{"gyro_dph", "Rate, deg/h"}};
  o.decimal_comma = true;
  auto r = parse_csv("time_s;\"Rate, deg/h\";t1_c;t2_c\n0;0,5;1;2\n1;0,75;1;2\n", o);
  INFO((r ? "" : r.error().message));
  REQUIRE(r);
  CHECK(r->gyro_dph[1] == 0.75);
}

TEST_CASE("csv dialect: errors keep the file's line and column, with the decimal-comma hint", "[csv]") {
  const auto e = error_of("# comment\ntime_s;gyro_dph;t1_c;t2_c\n0;1;2;3\n1;1,5;2;3\n");
  CHECK(e.code == CsvErrc::not_a_number);
  CHECK(e.line == 4);
  CHECK(e.column == 2);
  CHECK_THAT(e.message, Contains("'1,5'") && Contains("--decimal-comma"));
  const auto t = error_of("time_s\tgyro_dph\tt1_c\tt2_c\n0\t1\t2\t3\n1\tx\t2\t3\n");
  CHECK(t.line == 3);
  CHECK(t.column == 2);
}

TEST_CASE("csv dialect: every missing column at once, a bad delimiter and a decimal comma with ',' refused", "[csv]") {
  const auto e = error_of("time;rate;t1_c\n0;1;2\n");
  CHECK(e.code == CsvErrc::missing_column);
  CHECK_THAT(e.message, Contains("columns 'time_s', 'gyro_dph', 't2_c' not found"));
  CHECK_THAT(e.message, Contains("the header has: time,rate,t1_c"));
  CsvOptions semi;
  semi.delimiter = ',';
  const auto one = error_of("time_s;gyro_dph;t1_c;t2_c\n0;1;2;3\n", semi);
  CHECK_THAT(one.message, Contains("one column") && Contains("--delimiter"));
  CsvOptions dc;
  dc.decimal_comma = true;
  CHECK(error_of("time_s,gyro_dph,t1_c,t2_c\n0,1,2,3\n", dc).code == CsvErrc::bad_option);
  CsvOptions pipe;
  pipe.delimiter = '|';
  CHECK(error_of("time_s|gyro_dph|t1_c|t2_c\n0|1|2|3\n", pipe).code == CsvErrc::bad_option);
  // A header with both ',' and ';' is not guessed: ','.
  const auto both = error_of("time_s,gyro_dph;x,t1_c,t2_c\n0,1,2,3\n");
  CHECK(both.code == CsvErrc::missing_column);
}
