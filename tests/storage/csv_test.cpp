// Tests of the run CSV: the accepted format, every error with its line and column, column
// mapping, resampling, and the exact round trip to_csv -> parse_csv.
#include <catch2/catch.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <unistd.h>

#include "fogbench/storage/csv.hpp"

using namespace fogbench;
using storage::CsvErrc;
using storage::CsvOptions;
using Catch::Matchers::Contains;

namespace {

CsvOptions named(std::string name = "run.csv") {
  CsvOptions o;
  o.source_name = std::move(name);
  return o;
}

storage::CsvError parse_error(std::string_view text, const CsvOptions& options = named()) {
  auto r = storage::parse_csv(text, options);
  REQUIRE_FALSE(r.has_value());
  return r.error();
}

std::filesystem::path temp_path(const std::string& name) {
  auto dir = std::filesystem::temp_directory_path() /
             ("fogbench_csv_test_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  return dir / name;
}

}  // namespace

TEST_CASE("csv: the four required columns parse to exact doubles", "[csv]") {
  auto r = storage::parse_csv(
      "time_s,gyro_dph,t1_c,t2_c\n"
      "0,0.125,20.5,20.25\n"
      "1,-0.0625,21,20.75\n",
      named());
  REQUIRE(r.has_value());
  CHECK(r->name == "run.csv");
  CHECK(r->time_s == std::vector<double>{0, 1});
  CHECK(r->gyro_dph == std::vector<double>{0.125, -0.0625});
  CHECK(r->t1_c == std::vector<double>{20.5, 21});
  CHECK(r->t2_c == std::vector<double>{20.25, 20.75});
  CHECK_FALSE(r->has_setpoint());
  CHECK_FALSE(r->has_chamber());
  CHECK_FALSE(r->has_phase());
  CHECK_FALSE(r->has_step());
  CHECK_FALSE(r->has_flags());
}

TEST_CASE("csv: columns in any order, optional ones read, unknown ones ignored", "[csv]") {
  auto r = storage::parse_csv(
      "flags,operator,t2_c,phase,gyro_dph,step,chamber_c,time_s,setpoint_c,t1_c\n"
      "0,ann,20.1,settle,0.5,0,19.9,10,20,20.2\n"
      "5,ann,20.3,heating,0.6,3,25.5,11,30,20.4\n",
      named());
  REQUIRE(r.has_value());
  CHECK(r->time_s == std::vector<double>{10, 11});
  CHECK(r->gyro_dph == std::vector<double>{0.5, 0.6});
  CHECK(r->t1_c == std::vector<double>{20.2, 20.4});
  CHECK(r->t2_c == std::vector<double>{20.1, 20.3});
  CHECK(r->setpoint_c == std::vector<double>{20, 30});
  CHECK(r->chamber_c == std::vector<double>{19.9, 25.5});
  CHECK(r->phase == std::vector<model::Phase>{model::Phase::settle, model::Phase::heating});
  CHECK(r->step == std::vector<int>{0, 3});
  CHECK(r->flags == std::vector<std::uint8_t>{0, 5});
}

TEST_CASE("csv: comments, blank lines, CRLF, a BOM, spaces and quotes are accepted", "[csv]") {
  auto r = storage::parse_csv(
      "\xEF\xBB\xBF# exported by fogctl\r\n"
      "\r\n"
      "time_s, gyro_dph ,t1_c,t2_c,\"note, with comma\"\r\n"
      "  # a comment between rows\r\n"
      "0,1.5,20,21,\"a, b\"\r\n"
      "\r\n"
      "1, +2.5 ,20,21,x\r\n"
      "# trailing comment",
      named());
  REQUIRE(r.has_value());
  CHECK(r->time_s == std::vector<double>{0, 1});
  CHECK(r->gyro_dph == std::vector<double>{1.5, 2.5});
}

TEST_CASE("csv: --map names columns the file calls differently", "[csv]") {
  auto m = storage::parse_column_mapping("gyro_dph=Rate");
  REQUIRE(m.has_value());
  CHECK(m->canonical == "gyro_dph");
  CHECK(m->header == "Rate");

  CsvOptions o = named();
  o.column_map = {{"gyro_dph", "Rate"}, {"time_s", "t"}, {"t1_c", "T_coil"}};
  auto r = storage::parse_csv(
      "t,Rate,T_coil,t2_c,gyro_dph\n"
      "0,1.5,20,21,99\n"
      "1,2.5,22,23,99\n",
      o);
  REQUIRE(r.has_value());
  // The mapping wins over a column that merely carries the canonical name.
  CHECK(r->gyro_dph == std::vector<double>{1.5, 2.5});
  CHECK(r->t1_c == std::vector<double>{20, 22});

  SECTION("swapping two columns") {
    CsvOptions swap = named();
    swap.column_map = {{"t1_c", "t2_c"}, {"t2_c", "t1_c"}};
    auto s = storage::parse_csv("time_s,gyro_dph,t1_c,t2_c\n0,0,1,2\n", swap);
    REQUIRE(s.has_value());
    CHECK(s->t1_c == std::vector<double>{2});
    CHECK(s->t2_c == std::vector<double>{1});
  }
  SECTION("a malformed --map argument") {
    auto bad = storage::parse_column_mapping("gyro_dph");
    REQUIRE_FALSE(bad.has_value());
    CHECK(bad.error().code == CsvErrc::bad_option);
    CHECK_THAT(bad.error().message, Contains("gyro_dph=Rate"));
  }
  SECTION("an unknown canonical name") {
    CsvOptions bad = named();
    bad.column_map = {{"gyro", "Rate"}};
    auto e = parse_error("time_s,Rate,t1_c,t2_c\n0,0,0,0\n", bad);
    CHECK(e.code == CsvErrc::bad_option);
    CHECK_THAT(e.message, Contains("'gyro' is not a fogbench column"));
  }
  SECTION("a canonical name mapped twice") {
    CsvOptions bad = named();
    bad.column_map = {{"gyro_dph", "Rate"}, {"gyro_dph", "R2"}};
    CHECK(parse_error("time_s,Rate,t1_c,t2_c\n0,0,0,0\n", bad).code == CsvErrc::bad_option);
  }
  SECTION("a mapped column absent from the header") {
    CsvOptions bad = named();
    bad.column_map = {{"gyro_dph", "Rate"}};
    auto e = parse_error("# c\ntime_s,gyro,t1_c,t2_c\n0,0,0,0\n", bad);
    CHECK(e.code == CsvErrc::missing_column);
    CHECK(e.line == 2);
    CHECK_THAT(e.message, Contains("'Rate'"));
    CHECK_THAT(e.message, Contains("--map gyro_dph=Rate"));
    CHECK_THAT(e.message, Contains("time_s,gyro,t1_c,t2_c"));
  }
}

TEST_CASE("csv: every error names its place", "[csv][errors]") {
  SECTION("empty file") {
    auto e = parse_error("");
    CHECK(e.code == CsvErrc::empty);
    CHECK(e.line == 0);
    CHECK_THAT(e.message, Contains("run.csv: empty file"));
  }
  SECTION("only comments and blank lines") {
    CHECK(parse_error("# nothing\n\n  \n# here\n").code == CsvErrc::empty);
  }
  SECTION("a header but no data rows") {
    auto e = parse_error("# x\ntime_s,gyro_dph,t1_c,t2_c\n# y\n");
    CHECK(e.code == CsvErrc::no_data);
    CHECK_THAT(e.message, Contains("no data rows after the header on line 2"));
  }
  SECTION("missing required column: named, header listed, --map suggested") {
    auto e = parse_error("time_s,Rate,t1_c,t2_c\n0,0,0,0\n");
    CHECK(e.code == CsvErrc::missing_column);
    CHECK(e.line == 1);
    CHECK_THAT(e.message, Contains("'gyro_dph'"));
    CHECK_THAT(e.message, Contains("time_s,Rate,t1_c,t2_c"));
    CHECK_THAT(e.message, Contains("--map gyro_dph="));
  }
  SECTION("duplicate header name") {
    auto e = parse_error("time_s,gyro_dph,t1_c,t2_c,t1_c\n0,0,0,0,0\n");
    CHECK(e.code == CsvErrc::duplicate_column);
    CHECK(e.line == 1);
    CHECK(e.column == 5);
    CHECK(e.column_name == "t1_c");
    CHECK_THAT(e.message, Contains("also column 3"));
  }
  SECTION("a cell that is not a number") {
    auto e = parse_error(
        "time_s,gyro_dph,t1_c,t2_c\n"
        "0,0,0,0\n"
        "# comment\n"
        "1,1.2.3,0,0\n");
    CHECK(e.code == CsvErrc::not_a_number);
    CHECK(e.line == 4);
    CHECK(e.column == 2);
    CHECK(e.column_name == "gyro_dph");
    CHECK(e.message == "run.csv:4: column 2 'gyro_dph': not a number: '1.2.3'");
  }
  SECTION("a mapped column is named by both names") {
    CsvOptions o = named();
    o.column_map = {{"gyro_dph", "Rate"}};
    auto e = parse_error("time_s,Rate,t1_c,t2_c\n0,x,0,0\n", o);
    CHECK(e.column == 2);
    CHECK(e.column_name == "Rate");
    CHECK_THAT(e.message, Contains("column 2 'Rate' (gyro_dph): not a number: 'x'"));
  }
  SECTION("an empty cell") {
    auto e = parse_error("time_s,gyro_dph,t1_c,t2_c\n0,0,,0\n");
    CHECK(e.code == CsvErrc::not_a_number);
    CHECK(e.line == 2);
    CHECK(e.column == 3);
    CHECK_THAT(e.message, Contains("empty cell"));
  }
  SECTION("an empty cell on a row flagged missing is a reading not taken") {
    // flags bit 1 (missing): the empty gyro cell reads as NaN; the same row without the bit
    // is refused.
    auto r = fogbench::storage::parse_csv("time_s,gyro_dph,t1_c,t2_c,flags\n0,1,0,0,0\n1,,0,0,1\n", {});
    REQUIRE(r);
    CHECK(std::isnan(r->gyro_dph[1]));
    auto e = parse_error("time_s,gyro_dph,t1_c,t2_c,flags\n0,1,0,0,0\n1,,0,0,2\n");
    CHECK(e.line == 3);
    CHECK(e.column == 2);
    CHECK_THAT(e.message, Contains("missing bit"));
    // And a run with a missing reading survives the round trip through to_csv.
    auto back = fogbench::storage::parse_csv(fogbench::storage::to_csv(*r), {});
    REQUIRE(back);
    CHECK(std::isnan(back->gyro_dph[1]));
    CHECK(back->t1_c == r->t1_c);
  }
  SECTION("resampling towards a reading not taken flags the grid point missing") {
    // Samples at 0, 1.5, 3 s resampled at 1 s: the point at 1 s lies between 0 (good) and
    // 1.5 (gyro not read): its gyro is NaN, so it must carry the missing bit, not flags 0.
    CsvOptions o;
    o.resample_s = 1.0;
    auto r = fogbench::storage::parse_csv("time_s,gyro_dph,t1_c,t2_c,flags\n0,1,0,0,0\n1.5,,0,0,1\n3,1,0,0,0\n", o);
    REQUIRE(r);
    REQUIRE(r->size() == 4);
    CHECK(std::isnan(r->gyro_dph[1]));
    CHECK((r->flags[1] & fogbench::model::flag::missing) != 0);
    CHECK(r->flags[0] == 0);
  }
  SECTION("nan, inf and overflow") {
    auto nan = parse_error("time_s,gyro_dph,t1_c,t2_c\n0,0,0,0\n1,0,0,nan\n");
    CHECK(nan.code == CsvErrc::not_finite);
    CHECK(nan.line == 3);
    CHECK(nan.column == 4);
    CHECK_THAT(nan.message, Contains("'nan' is not a finite number"));
    auto inf = parse_error("time_s,gyro_dph,t1_c,t2_c\n0,-inf,0,0\n");
    CHECK(inf.code == CsvErrc::not_finite);
    CHECK(inf.column == 2);
    auto big = parse_error("time_s,gyro_dph,t1_c,t2_c\n0,1e400,0,0\n");
    CHECK(big.code == CsvErrc::not_finite);
    CHECK_THAT(big.message, Contains("1e400"));
    // Underflow is not an error: the nearest double is zero.
    auto tiny = storage::parse_csv("time_s,gyro_dph,t1_c,t2_c\n0,1e-400,0,0\n", named());
    REQUIRE(tiny.has_value());
    CHECK(tiny->gyro_dph[0] == 0.0);
  }
  SECTION("a row with too few fields") {
    auto e = parse_error("time_s,gyro_dph,t1_c,t2_c\n0,0,0,0\n1,0,0\n");
    CHECK(e.code == CsvErrc::field_count);
    CHECK(e.line == 3);
    CHECK_THAT(e.message, Contains("too few fields: 3"));
    CHECK_THAT(e.message, Contains("'t2_c'"));
  }
  SECTION("a row with too many fields") {
    auto e = parse_error("time_s,gyro_dph,t1_c,t2_c\n0,0,0,0,7,8\n");
    CHECK(e.code == CsvErrc::field_count);
    CHECK(e.line == 2);
    CHECK_THAT(e.message, Contains("6 fields but the header (line 1) has 4"));
  }
  SECTION("an unterminated quote") {
    auto e = parse_error("time_s,gyro_dph,t1_c,t2_c,note\n0,0,0,0,\"open\n");
    CHECK(e.code == CsvErrc::bad_quote);
    CHECK(e.line == 2);
    CHECK(e.column == 5);
  }
  SECTION("time equal to the previous row's") {
    auto e = parse_error("time_s,gyro_dph,t1_c,t2_c\n0,0,0,0\n1,0,0,0\n\n1,0,0,0\n");
    CHECK(e.code == CsvErrc::time_not_increasing);
    CHECK(e.line == 5);
    CHECK(e.column == 1);
    CHECK_THAT(e.message, Contains("1 is not after 1 on line 3"));
  }
  SECTION("time going backwards, in a non-first column") {
    auto e = parse_error("gyro_dph,time_s,t1_c,t2_c\n0,5,0,0\n0,4,0,0\n");
    CHECK(e.code == CsvErrc::time_not_increasing);
    CHECK(e.line == 3);
    CHECK(e.column == 2);
  }
  SECTION("time not evenly spaced") {
    // Steps 1,1,1,2,1: the median is 1 s; the 2 s step ends on row 5 (line 6).
    auto e = parse_error(
        "time_s,gyro_dph,t1_c,t2_c\n0,0,0,0\n1,0,0,0\n2,0,0,0\n3,0,0,0\n5,0,0,0\n6,0,0,0\n");
    CHECK(e.code == CsvErrc::time_uneven);
    CHECK(e.line == 6);
    CHECK(e.column == 1);
    CHECK_THAT(e.message, Contains("time step 2 s (3 on line 5 -> 5)"));
    CHECK_THAT(e.message, Contains("median step is 1 s"));
  }
  SECTION("spacing within 1% is even") {
    // %.3f time at 1 Hz with 5 ms jitter: 0.5% of the step.
    auto r = storage::parse_csv(
        "time_s,gyro_dph,t1_c,t2_c\n0.000,0,0,0\n1.005,0,0,0\n2.000,0,0,0\n3.001,0,0,0\n",
        named());
    CHECK(r.has_value());
  }
  SECTION("an unknown phase") {
    auto e = parse_error("time_s,gyro_dph,t1_c,t2_c,phase\n0,0,0,0,ramp\n");
    CHECK(e.code == CsvErrc::bad_value);
    CHECK(e.line == 2);
    CHECK(e.column == 5);
    CHECK_THAT(e.message, Contains("unknown phase 'ramp'"));
  }
  SECTION("a step that is not an integer") {
    auto e = parse_error("time_s,gyro_dph,t1_c,t2_c,step\n0,0,0,0,1.5\n");
    CHECK(e.code == CsvErrc::not_a_number);
    CHECK(e.column == 5);
    CHECK_THAT(e.message, Contains("not an integer: '1.5'"));
  }
  SECTION("flags out of 0..255") {
    auto e = parse_error("time_s,gyro_dph,t1_c,t2_c,flags\n0,0,0,0,256\n");
    CHECK(e.code == CsvErrc::bad_value);
    CHECK(e.column == 5);
  }
  SECTION("a bad resample interval") {
    CsvOptions o = named();
    o.resample_s = 0.0;
    CHECK(parse_error("time_s,gyro_dph,t1_c,t2_c\n0,0,0,0\n", o).code == CsvErrc::bad_option);
  }
  SECTION("resampling onto more than 10 million rows (a unit mistake) is refused before allocating") {
    CsvOptions o = named();
    o.resample_s = 2.0;
    // What the fuzzer found: two rows 2e8 s apart asked for 1e8 rows, 6 GB.
    auto e = parse_error("time_s,gyro_dph,t1_c,t2_c\n0,1,20,20\n199999999,1.4,20.4,20.2\n", o);
    CHECK(e.code == CsvErrc::bad_option);
    CHECK_THAT(e.message, Contains("would make 1e+08 rows"));
    // 10 million rows exactly is still a run.
    o.resample_s = 1.0;
    auto ok = storage::parse_csv("time_s,gyro_dph,t1_c,t2_c\n0,1,20,20\n9999999,1.4,20.4,20.2\n", o);
    REQUIRE(ok);
    CHECK(ok->size() == 10000000u);
  }
}

TEST_CASE("csv: resampling onto an even grid", "[csv][resample]") {
  CsvOptions o = named();
  o.resample_s = 1.0;
  // Source samples at 0, 0.5, 2, 3 s. Grid 0,1,2,3 s.
  auto r = storage::parse_csv(
      "time_s,gyro_dph,t1_c,t2_c,setpoint_c,phase,step,flags\n"
      "0,0,10,20,5,settle,0,0\n"
      "0.5,1,11,20,5,hold,1,2\n"
      "2,4,14,23,5,heating,2,0\n"
      "3,4,15,23,5,heating,2,0\n",
      o);
  REQUIRE(r.has_value());
  CHECK(r->time_s == std::vector<double>{0, 1, 2, 3});
  // t=1 lies a third of the way from 0.5 (gyro 1) to 2 (gyro 4): 1 + (1/3)*3 = 2.
  CHECK(r->gyro_dph[1] == Approx(2.0).epsilon(1e-12));
  // t1: 11 + (1/3)*3 = 12; t2: 20 + (1/3)*3 = 21.
  CHECK(r->t1_c[1] == Approx(12.0).epsilon(1e-12));
  CHECK(r->t2_c[1] == Approx(21.0).epsilon(1e-12));
  CHECK(r->setpoint_c == std::vector<double>{5, 5, 5, 5});
  // Grid points on a source sample copy it exactly.
  CHECK(r->gyro_dph[0] == 0);
  CHECK(r->gyro_dph[2] == 4);
  // Categorical columns come from the nearest previous sample (0.5 s for t=1).
  CHECK(r->phase == std::vector<model::Phase>{model::Phase::settle, model::Phase::hold,
                                              model::Phase::heating, model::Phase::heating});
  CHECK(r->step == std::vector<int>{0, 1, 2, 2});
  // Source steps 0.5, 1.5, 1: median 1, gap threshold 1.5 s, so the 1.5 s interval is no gap.
  CHECK(r->flags == std::vector<std::uint8_t>{0, 2, 0, 0});

  SECTION("points inside a gap are flagged missing") {
    CsvOptions g = named();
    g.resample_s = 1.0;
    // Steps 1,1,3,1,1: median 1 s; the 3 s gap holds grid points 3 and 4.
    auto s = storage::parse_csv(
        "time_s,gyro_dph,t1_c,t2_c\n0,0,0,0\n1,1,0,0\n2,2,0,0\n5,5,0,0\n6,6,0,0\n7,7,0,0\n",
        g);
    REQUIRE(s.has_value());
    CHECK(s->size() == 8);
    CHECK(s->gyro_dph[3] == Approx(3.0).epsilon(1e-12));
    CHECK(s->flags == std::vector<std::uint8_t>{0, 0, 0, model::flag::missing,
                                                model::flag::missing, 0, 0, 0});
  }
  SECTION("evenly spaced input gets no flags column") {
    CsvOptions g = named();
    g.resample_s = 0.5;
    auto s = storage::parse_csv("time_s,gyro_dph,t1_c,t2_c\n0,0,0,0\n1,1,0,0\n2,4,0,0\n", g);
    REQUIRE(s.has_value());
    CHECK(s->time_s == std::vector<double>{0, 0.5, 1, 1.5, 2});
    CHECK(s->gyro_dph == std::vector<double>{0, 0.5, 1, 2.5, 4});
    CHECK_FALSE(s->has_flags());
  }
}

TEST_CASE("csv: to_csv -> parse_csv reproduces the run exactly", "[csv][roundtrip]") {
  std::mt19937_64 rng(12345);
  std::uniform_real_distribution<double> u(-1e3, 1e3);
  model::RunData run;
  run.name = "generated";
  const int n = 2000;
  for (int i = 0; i < n; ++i) {
    run.time_s.push_back(0.25 * i + 1e-6);  // not representable with %.3f
    run.gyro_dph.push_back(u(rng) * 1e-7);  // tiny values need all 17 digits
    run.t1_c.push_back(u(rng));
    run.t2_c.push_back(u(rng));
    run.setpoint_c.push_back(std::round(u(rng)));
    run.chamber_c.push_back(-0.0);
    run.phase.push_back(static_cast<model::Phase>(i % 5));
    run.step.push_back(i / 7 - 3);
    run.flags.push_back(static_cast<std::uint8_t>(i % 256));
  }
  const std::string text = storage::to_csv(run);
  CHECK(text.starts_with("time_s,gyro_dph,t1_c,t2_c,setpoint_c,chamber_c,phase,step,flags\n"));
  auto back = storage::parse_csv(text, named("generated"));
  REQUIRE(back.has_value());
  CHECK(back->time_s == run.time_s);
  CHECK(back->gyro_dph == run.gyro_dph);
  CHECK(back->t1_c == run.t1_c);
  CHECK(back->t2_c == run.t2_c);
  CHECK(back->setpoint_c == run.setpoint_c);
  REQUIRE(back->chamber_c.size() == run.chamber_c.size());
  CHECK(std::signbit(back->chamber_c[0]));
  CHECK(back->phase == run.phase);
  CHECK(back->step == run.step);
  CHECK(back->flags == run.flags);
  CHECK(storage::to_csv(*back) == text);

  SECTION("only the columns the run has are written") {
    model::RunData small;
    small.time_s = {0, 1};
    small.gyro_dph = {0.1, 0.2};
    small.t1_c = {1, 2};
    small.t2_c = {3, 4};
    small.step = {7, 8};
    CHECK(storage::to_csv(small) == "time_s,gyro_dph,t1_c,t2_c,step\n0,0.1,1,3,7\n1,0.2,2,4,8\n");
  }
}

TEST_CASE("csv: files", "[csv][file]") {
  SECTION("a missing file is an error naming it") {
    auto r = storage::read_csv_file("/nonexistent/dir/run.csv");
    REQUIRE_FALSE(r.has_value());
    CHECK(r.error().code == CsvErrc::io);
    CHECK_THAT(r.error().message, Contains("'/nonexistent/dir/run.csv'"));
    CHECK_THAT(r.error().message, Contains("No such file"));
  }
  SECTION("a directory is an error") {
    auto r = storage::read_csv_file(std::filesystem::temp_directory_path());
    REQUIRE_FALSE(r.has_value());
    CHECK(r.error().code == CsvErrc::io);
  }
  SECTION("write then read; errors carry the path as source") {
    model::RunData run;
    run.time_s = {0, 1, 2};
    run.gyro_dph = {0.1, 0.2, 0.3};
    run.t1_c = {20, 21, 22};
    run.t2_c = {20, 20.5, 21};
    const auto path = temp_path("rt.csv");
    REQUIRE(storage::write_csv_file(path, run).has_value());
    auto back = storage::read_csv_file(path);
    REQUIRE(back.has_value());
    CHECK(back->name == path.string());
    CHECK(back->gyro_dph == run.gyro_dph);

    std::ofstream(path) << "time_s,gyro_dph,t1_c,t2_c\n0,0,0,x\n";
    auto bad = storage::read_csv_file(path);
    REQUIRE_FALSE(bad.has_value());
    CHECK(bad.error().source == path.string());
    CHECK_THAT(bad.error().message, Contains(path.string() + ":2: column 4 't2_c'"));
    std::filesystem::remove_all(path.parent_path());
  }
  SECTION("writing into a missing directory is an error") {
    model::RunData run;
    auto r = storage::write_csv_file("/nonexistent/dir/out.csv", run);
    REQUIRE_FALSE(r.has_value());
    CHECK(r.error().code == CsvErrc::io);
    CHECK_THAT(r.error().message, Contains("/nonexistent/dir/out.csv"));
  }
}

TEST_CASE("CSV: columns asked to be skipped are not read, nor checked") {
  // chamber_c holds garbage that would be an error if read.
  fogbench::storage::CsvOptions o;
  o.skip = {"chamber_c", "step"};
  auto r = fogbench::storage::parse_csv("time_s,gyro_dph,t1_c,t2_c,chamber_c,step\n0,1,2,3,x,y\n1,1,2,3,x,y\n", o);
  REQUIRE(r);
  CHECK_FALSE(r->has_chamber());
  CHECK_FALSE(r->has_step());
  // A required column cannot be skipped.
  o.skip = {"t1_c"};
  auto req = fogbench::storage::parse_csv("time_s,gyro_dph,t2_c\n0,1,3\n", o);
  REQUIRE_FALSE(req);
  CHECK(req.error().code == fogbench::storage::CsvErrc::missing_column);
}

TEST_CASE("CSV: a large file (parsed in two halves) reads exactly, and its errors keep their lines") {
  // 200,000 rows of ~40 bytes: 8 MB, above the 4 MB where the parser splits the work.
  std::string text = "time_s,gyro_dph,t1_c,t2_c\n";
  const int n = 200000;
  for (int i = 0; i < n; ++i)
    text += std::to_string(i) + "," + std::to_string(-8.0 + i * 1e-6) + ",20.5,19.25\n";
  auto r = fogbench::storage::parse_csv(text, {});
  REQUIRE(r);
  REQUIRE(r->size() == static_cast<std::size_t>(n));
  for (int i : {0, 1, n / 2 - 1, n / 2, n / 2 + 1, n - 1}) {
    CHECK(r->time_s[static_cast<std::size_t>(i)] == i);
    CHECK(r->gyro_dph[static_cast<std::size_t>(i)] == std::stod(std::to_string(-8.0 + i * 1e-6)));
  }
  // An error in the second half: the line number is the file's (row 150,000 is line 150,002).
  std::string bad = text;
  const std::string row = "\n150000,";
  const auto at = bad.find(row);
  REQUIRE(at != std::string::npos);
  bad.insert(at + row.size(), "x");
  auto e = fogbench::storage::parse_csv(bad, {});
  REQUIRE_FALSE(e);
  CHECK(e.error().line == 150002);
  CHECK(e.error().column == 2);
  // Time that goes back exactly at the split is still caught.
  std::string back = text;
  const auto mid = back.find("\n100000,");
  back.replace(mid + 1, 6, "99998");
  auto t = fogbench::storage::parse_csv(back, {});
  REQUIRE_FALSE(t);
  CHECK(t.error().code == fogbench::storage::CsvErrc::time_not_increasing);
  CHECK(t.error().line == 100002);
}

TEST_CASE("CSV: rows in any accepted spelling read the same as plain ones", "[csv]") {
  // The parser reads plain rows on a quick path and hands every other row to the general one;
  // both must give the same values. Each row here is spelled one of several accepted ways.
  const std::string header = "time_s,gyro_dph,t1_c,t2_c,setpoint_c,chamber_c,phase,step,flags,note\n";
  std::string plain = header, mixed = header;
  const int n = 400;
  std::vector<double> gyro;
  for (int i = 0; i < n; ++i) {
    const double g = -8.0 + 0.0123456789012345 * i;
    gyro.push_back(g);
    char gs[40];
    std::snprintf(gs, sizeof gs, "%.17g", g);
    const std::string t = std::to_string(i), ph = i % 3 ? "heating" : "hold", st = std::to_string(i / 100);
    const std::string fl = std::to_string(i % 2 * 4);
    plain += t + "," + gs + ",20.5,19.25,21,20.75," + ph + "," + st + "," + fl + ",n\n";
    switch (i % 6) {
      case 0: mixed += t + "," + gs + ",20.5,19.25,21,20.75," + ph + "," + st + "," + fl + ",n\n"; break;
      case 1: mixed += t + ", " + gs + " ,20.5,\t19.25,21,20.75, " + ph + " ," + st + "," + fl + ",n\n"; break;
      case 2: mixed += t + ",+" + gs + ",+20.5,19.25,21,20.75," + ph + ",+" + st + "," + fl + ",n\n"; break;
      case 3: mixed += t + "," + gs + ",20.5,19.25,21,20.75," + ph + "," + st + "," + fl + ",\"a, \"\"b\"\", c\"\n"; break;
      case 4: mixed += t + "," + gs + ",20.5,19.25,21,20.75,\"" + ph + "\"," + st + "," + fl + ",n\r\n"; break;
      case 5: mixed += t + "," + gs + ",2.05e1,1925e-2,21,20.75," + ph + "," + st + "," + fl + ",\n# between\n"; break;
    }
  }
  auto a = storage::parse_csv(plain, named());
  auto b = storage::parse_csv(mixed, named());
  REQUIRE(a);
  REQUIRE(b);
  REQUIRE(a->size() == static_cast<std::size_t>(n));
  CHECK(a->gyro_dph == gyro);
  CHECK(b->time_s == a->time_s);
  CHECK(b->gyro_dph == a->gyro_dph);
  CHECK(b->t1_c == a->t1_c);
  CHECK(b->t2_c == a->t2_c);
  CHECK(b->setpoint_c == a->setpoint_c);
  CHECK(b->chamber_c == a->chamber_c);
  CHECK(b->phase == a->phase);
  CHECK(b->step == a->step);
  CHECK(b->flags == a->flags);
  // A quoted ignored cell holding commas is one cell, not several: a quick path that split it
  // at its comma would see too many fields.
  auto q = storage::parse_csv("time_s,note,gyro_dph,t1_c,t2_c\n0,\"1,2\",3.5,20,21\n1,x,4.5,20,21\n", named());
  REQUIRE(q);
  CHECK(q->gyro_dph == std::vector<double>{3.5, 4.5});
  // ... so a row one cell short stays one cell short, even when its quoted comma would make
  // the count come out right.
  auto s = storage::parse_csv("time_s,n1,n2,gyro_dph,t1_c,t2_c\n0,\"a,b\",3.5,20,21\n", named());
  REQUIRE_FALSE(s);
  CHECK(s.error().code == CsvErrc::field_count);
  CHECK(s.error().line == 2);
}

TEST_CASE("csv: since_power_on_s round-trips, unknown cells stay unknown, and a file without it has none",
          "[csv][power_on]") {
  // The gyro was already on when the daemon started (unknown: empty cells, on rows that are not
  // flagged missing), then restarted at 2 s: 0.4 s after power-on at the sample of 2 s.
  const std::string text =
      "time_s,gyro_dph,t1_c,t2_c,flags,since_power_on_s\n"
      "0,0.1,20,20.5,0,\n"
      "1,0.2,20,20.5,0,\n"
      "2,0.3,20,20.5,0,0.4\n"
      "3,0.4,20,20.5,0,1.4\n";
  auto run = storage::parse_csv(text, named("power.csv"));
  REQUIRE(run.has_value());
  REQUIRE(run->has_power_on());
  REQUIRE(run->since_power_on_s.size() == 4);
  CHECK(std::isnan(run->since_power_on_s[0]));
  CHECK(std::isnan(run->since_power_on_s[1]));
  CHECK(run->since_power_on_s[2] == 0.4);
  CHECK(run->since_power_on_s[3] == 1.4);
  CHECK(run->flags == std::vector<std::uint8_t>{0, 0, 0, 0});  // unknown is not missing
  CHECK(storage::to_csv(*run) == text);  // written last, unknown as empty cells

  // In any column order, and under --map.
  auto mapped = storage::parse_csv("t,g,a,b,on\n0,1,2,3,5.5\n1,1,2,3,6.5\n", [] {
    CsvOptions o;
    o.source_name = "mapped.csv";
    for (auto m : {"time_s=t", "gyro_dph=g", "t1_c=a", "t2_c=b", "since_power_on_s=on"})
      o.column_map.push_back(*storage::parse_column_mapping(m));
    return o;
  }());
  REQUIRE(mapped.has_value());
  CHECK(mapped->since_power_on_s == std::vector<double>{5.5, 6.5});

  // A file without the column: not recorded, so empty (never made up from time_s).
  auto without = storage::parse_csv("time_s,gyro_dph,t1_c,t2_c\n0,1,2,3\n1,1,2,3\n", named("old.csv"));
  REQUIRE(without.has_value());
  CHECK_FALSE(without->has_power_on());
  CHECK(storage::to_csv(*without).find("since_power_on_s") == std::string::npos);

  // A bad value names the column.
  auto bad = storage::parse_csv("time_s,gyro_dph,t1_c,t2_c,since_power_on_s\n0,1,2,3,soon\n", named("bad.csv"));
  REQUIRE_FALSE(bad.has_value());
  CHECK(bad.error().column == 5);
  CHECK_THAT(bad.error().message, Contains("since_power_on_s"));

  SECTION("resampling runs the time on at 1 s per s, and from the restart after one") {
    // Samples 2 s apart; the gyro restarted between 2 and 4 s (10 s on at 2 s, 0.5 s at 4 s).
    CsvOptions o = named("uneven.csv");
    o.resample_s = 1.0;
    auto r = storage::parse_csv("time_s,gyro_dph,t1_c,t2_c,since_power_on_s\n0,1,2,3,8\n2,1,2,3,10\n4,1,2,3,0.5\n", o);
    REQUIRE(r.has_value());
    REQUIRE(r->since_power_on_s.size() == 5);
    CHECK(r->since_power_on_s[1] == 9.0);   // 8 + 1
    CHECK(r->since_power_on_s[2] == 10.0);
    CHECK(r->since_power_on_s[3] == 11.0);  // 0.5 - 1 < 0: the restart is after 3 s
    CHECK(r->since_power_on_s[4] == 0.5);
  }
}

TEST_CASE("csv: compensated_dph round-trips with empty cells where the daemon computed none, and a file without it still reads",
          "[csv][compensated]") {
  // The live compensation warms up (empty) and goes on; the empty cells are no missing reading.
  const std::string text =
      "time_s,gyro_dph,t1_c,t2_c,flags,compensated_dph\n"
      "0,0.1,20,20.5,0,\n"
      "1,0.2,20,20.5,0,\n"
      "2,0.3,20,20.5,0,0.012\n"
      "3,0.4,20,20.5,0,-0.25\n";
  auto run = storage::parse_csv(text, named("live.csv"));
  REQUIRE(run.has_value());
  REQUIRE(run->has_compensated());
  CHECK(std::isnan(run->compensated_dph[0]));
  CHECK(std::isnan(run->compensated_dph[1]));
  CHECK(run->compensated_dph[2] == 0.012);
  CHECK(run->compensated_dph[3] == -0.25);
  CHECK(run->flags == std::vector<std::uint8_t>{0, 0, 0, 0});
  CHECK(storage::to_csv(*run) == text);

  // Beside since_power_on_s, which comes first; a bad value names the column.
  auto both = storage::parse_csv("time_s,gyro_dph,t1_c,t2_c,since_power_on_s,compensated_dph\n0,1,2,3,4,5\n", named("both.csv"));
  REQUIRE(both.has_value());
  CHECK(both->since_power_on_s == std::vector<double>{4});
  CHECK(both->compensated_dph == std::vector<double>{5});
  auto bad = storage::parse_csv("time_s,gyro_dph,t1_c,t2_c,compensated_dph\n0,1,2,3,x\n", named("bad.csv"));
  REQUIRE_FALSE(bad.has_value());
  CHECK(bad.error().column == 5);
  CHECK_THAT(bad.error().message, Contains("compensated_dph"));

  // A file written before the column existed reads as before: none recorded.
  auto old = storage::parse_csv("time_s,gyro_dph,t1_c,t2_c,flags,since_power_on_s\n0,1,2,3,0,\n1,1,2,3,0,1\n", named("old.csv"));
  REQUIRE(old.has_value());
  CHECK_FALSE(old->has_compensated());
  CHECK(storage::to_csv(*old).find("compensated_dph") == std::string::npos);
}

TEST_CASE("csv: a rate table's export reads back its plateau, rate_in_dps and rate_out_dps (round trip)", "[csv][rate]") {
  model::RunData d;
  for (int i = 0; i < 6; ++i) {
    d.time_s.push_back(i);
    d.gyro_dph.push_back(i == 3 ? std::nan("") : 36000.0 * (i < 2 ? 1 : -1) + 0.125 * i);
    d.t1_c.push_back(20.0 + 0.01 * i);
    d.t2_c.push_back(20.5);
    d.step.push_back(i < 4 ? 1 : 2);
    d.flags.push_back(i == 3 ? model::flag::missing : 0);
    d.rate_in_dps.push_back(i < 2 ? 10.0 : i < 4 ? -10.0 : 0.0);
  }
  const std::string csv = storage::to_csv(d);
  REQUIRE_THAT(csv, Contains(",plateau,rate_in_dps,rate_out_dps"));
  auto r = storage::parse_csv(csv, named());
  INFO((r ? std::string() : r.error().message));
  REQUIRE(r.has_value());
  REQUIRE(r->has_rate_in());
  CHECK(r->rate_in_dps == d.rate_in_dps);
  CHECK(r->step == d.step);
  CHECK(storage::to_csv(*r) == csv);  // byte for byte
  // The missing second keeps its empty gyro_dph and rate_out_dps.
  CHECK(std::isnan(r->gyro_dph[3]));

  SECTION("without a step column, the plateau is the step") {
    auto s = storage::parse_csv(
        "time_s,gyro_dph,t1_c,t2_c,plateau,rate_in_dps,rate_out_dps\n0,36000,20,20,4,10,10\n1,-36000,20,20,4,-10,-10\n",
        named());
    REQUIRE(s.has_value());
    CHECK(s->step == std::vector<int>{4, 4});
    CHECK(s->rate_in_dps == std::vector<double>{10, -10});
  }
  SECTION("resampled, the commanded rate is held, never interpolated") {
    CsvOptions o = named();
    o.resample_s = 0.5;
    auto s = storage::parse_csv(
        "time_s,gyro_dph,t1_c,t2_c,rate_in_dps\n0,36000,20,20,10\n1,-36000,20,20,-10\n2,-36000,20,20,-10\n", o);
    REQUIRE(s.has_value());
    CHECK(s->rate_in_dps == std::vector<double>{10, 10, -10, -10, -10});
  }
}

TEST_CASE("csv: a rate table's columns that disagree with the others are named", "[csv][rate][errors]") {
  const std::string head = "time_s,gyro_dph,t1_c,t2_c,step,plateau,rate_in_dps,rate_out_dps\n";
  auto e = parse_error(head + "0,36000,20,20,1,1,10,10\n1,36000,20,20,1,1,10,9.5\n");
  CHECK(e.message == "run.csv:3: column 8 'rate_out_dps': 9.5 deg/s is not gyro_dph / 3600 (10 deg/s): rate_out_dps is "
                     "the gyro's output in deg/s");
  auto p = parse_error(head + "0,36000,20,20,1,2,10,10\n");
  CHECK(p.message == "run.csv:2: column 6 'plateau': plateau 2 but step 1: the plateau is the profile step");
  auto x = parse_error(head + "0,36000,20,20,1,1,x,10\n");
  CHECK_THAT(x.message, Contains("run.csv:2: column 7 'rate_in_dps': not a number: 'x'"));
}
