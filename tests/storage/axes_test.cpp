// Three-axis units in the store and its CSV (issue 29 point 3): schema 13's y and z per second and
// axes per run unit, an upgrade from 12 that keeps every row, the export of a three-axis unit
// with gyro_y_dph and gyro_z_dph (a one-axis unit's exactly as before) and the CSV round trip.
#include <catch2/catch.hpp>

#include <cmath>

#include "fogbench/storage/csv.hpp"
#include "store_fixture.hpp"

using namespace fogbench;
using namespace fogbench::storage;
using namespace fogbench::storage::testing;
using Catch::Matchers::Contains;

namespace {

// Unit 0 has three axes, unit 1 one; unit 0's z is silent (NaN, flagged missing) at t_s 2.
std::int64_t three_axis_run(Store& store) {
  NewRun r = two_unit_run();
  r.unit_axes = {3, 1};
  auto id = store.create_run(r);
  REQUIRE(id.has_value());
  std::vector<SampleRow> rows;
  for (int t = 0; t < 4; ++t) {
    SampleRow a = sample(0, t);
    a.gyro_y_dph = 100.0 + t;
    a.gyro_z_dph = t == 2 ? kNoValue : 200.0 + t;
    if (t == 2) a.flags = model::flag::missing;
    rows.push_back(a);
    rows.push_back(sample(1, t));
  }
  REQUIRE(store.append_samples(*id, rows).has_value());
  return *id;
}

}  // namespace

TEST_CASE("store axes: schema 13 stores a three-axis unit's y and z and each unit's axes", "[store][axes]") {
  CHECK(Store::current_schema_version() >= 13);
  TempDir tmp;
  auto store = open_ok(tmp / "a.db");
  const auto id = three_axis_run(store);
  auto d = store.get_run(id);
  REQUIRE(d.has_value());
  REQUIRE(d->run.units.size() == 2);
  CHECK(d->run.units[0].axes == 3);
  CHECK(d->run.units[1].axes == 1);

  auto rows = store.get_samples(id, 0, 0, 10);
  REQUIRE(rows->size() == 4);
  CHECK(rows->at(1).gyro_y_dph == 101.0);
  CHECK(rows->at(1).gyro_z_dph == 201.0);
  CHECK(std::isnan(rows->at(2).gyro_z_dph));  // NULL in the file, NaN read back
  auto one = store.get_samples(id, 1, 0, 10);
  CHECK(std::isnan(one->at(0).gyro_y_dph));
  CHECK(std::isnan(one->at(0).gyro_z_dph));
  Raw raw(tmp / "a.db");
  CHECK(raw.integer("SELECT count(*) FROM samples WHERE unit_index = 1 AND gyro_y_dph IS NULL AND gyro_z_dph IS NULL") == 4);
  CHECK(raw.integer("SELECT count(*) FROM sample_view WHERE gyro_y_dph IS NOT NULL") == 4);
}

TEST_CASE("store axes: a version 12 file upgrades with its runs one-axis and their rows unchanged", "[store][axes][schema]") {
  TempDir tmp;
  const auto path = tmp / "old.db";
  std::int64_t id = 0;
  {
    auto store = open_ok(path);
    id = store.create_run(two_unit_run()).value();
    REQUIRE(store.append_samples(id, std::vector<SampleRow>{sample(0, 0), sample(0, 1)}).has_value());
  }
  {
    // Back to what version 12 had: no axes columns (nor version 14's per-axis models, nor
    // version 15's per-axis thermistors).
    Raw raw(path);
    raw.exec("DROP VIEW sample_view");
    for (const char* c : {"t1_y_c", "t2_y_c", "t1_z_c", "t2_z_c"}) raw.exec(std::string("ALTER TABLE samples DROP COLUMN ") + c);
    raw.exec("CREATE VIEW sample_view AS SELECT * FROM samples");
    raw.exec("DROP INDEX models_serial_axis");
    raw.exec("ALTER TABLE models DROP COLUMN axis");
    raw.exec("ALTER TABLE verdicts DROP COLUMN axes_json");
    raw.exec("DROP VIEW sample_view");
    raw.exec("ALTER TABLE samples DROP COLUMN gyro_y_dph");
    raw.exec("ALTER TABLE samples DROP COLUMN gyro_z_dph");
    raw.exec("ALTER TABLE run_units DROP COLUMN axes");
    raw.exec("CREATE VIEW sample_view AS SELECT * FROM samples");
    raw.exec("PRAGMA user_version = 12");
  }
  auto store = open_ok(path);
  {
    Raw raw(path);
    CHECK(raw.integer("PRAGMA user_version") == Store::current_schema_version());
  }
  auto d = store.get_run(id);
  REQUIRE(d.has_value());
  CHECK(d->run.units[0].axes == 1);
  auto rows = store.get_samples(id, 0, 0, 10);
  REQUIRE(rows->size() == 2);
  CHECK(rows->at(1).gyro_dph == sample(0, 1).gyro_dph);
  CHECK(std::isnan(rows->at(1).gyro_y_dph));
  auto data = store.export_run(id, 0);
  REQUIRE(data.has_value());
  CHECK_FALSE(data->has_axes());
}

TEST_CASE("store axes: a three-axis unit exports gyro_y_dph and gyro_z_dph, a one-axis unit as before, round trip", "[store][axes][csv]") {
  TempDir tmp;
  auto store = open_ok(tmp / "a.db");
  const auto id = three_axis_run(store);

  auto x = store.export_run(id, 0);
  REQUIRE(x.has_value());
  REQUIRE(x->has_axes());
  const std::string text = to_csv(*x);
  CHECK_THAT(text, Contains("time_s,gyro_dph,t1_c,t2_c,setpoint_c,chamber_c,phase,step,flags,gyro_y_dph,gyro_z_dph\n"));
  CHECK_THAT(text, Contains(",1,102,\n"));  // t_s 2: flagged missing, z empty
  auto one = store.export_run(id, 1);
  REQUIRE(one.has_value());
  CHECK_FALSE(one->has_axes());
  CHECK(to_csv(*one).find("gyro_y_dph") == std::string::npos);

  // parse_csv reads them back, exactly; the empty cell is allowed on the row flagged missing.
  CsvOptions o;
  o.source_name = "x.csv";
  auto back = parse_csv(text, o);
  REQUIRE(back.has_value());
  REQUIRE(back->has_axes());
  REQUIRE(back->gyro_y_dph.size() == 4);
  for (std::size_t i = 0; i < 4; ++i) {
    CHECK(back->gyro_y_dph[i] == x->gyro_y_dph[i]);
    if (i == 2)
      CHECK(std::isnan(back->gyro_z_dph[i]));
    else
      CHECK(back->gyro_z_dph[i] == x->gyro_z_dph[i]);
  }
  CHECK(to_csv(*back) == text);

  // Imported again, the unit is three-axis and exports the same file.
  ImportOptions io;
  io.serial = "FOG-001";
  auto again = store.import_run(*back, io);
  REQUIRE(again.has_value());
  CHECK(store.get_run(*again)->run.units.at(0).axes == 3);
  auto x2 = store.export_run(*again, 0);
  REQUIRE(x2.has_value());
  CHECK(to_csv(*x2) == text);

}

TEST_CASE("store axes: per-axis thermistors stored per second, exported as their CSV columns, imported back", "[store][axes][cross_axis]") {
  TempDir tmp;
  auto store = open_ok(tmp / "a.db");
  NewRun r = two_unit_run();
  r.unit_axes = {3, 1};
  const auto id = store.create_run(r).value();
  std::vector<SampleRow> rows;
  for (int t = 0; t < 4; ++t) {
    SampleRow a = sample(0, t);
    a.gyro_y_dph = 100.0 + t;
    a.gyro_z_dph = 200.0 + t;
    a.t1_y_c = 31.0 + t;
    a.t2_y_c = 32.0 + t;
    a.t1_z_c = 33.0 + t;
    a.t2_z_c = t == 2 ? kNoValue : 34.0 + t;  // z's outer wall not read that second
    if (t == 2) a.flags = model::flag::missing;
    rows.push_back(a);
    rows.push_back(sample(1, t));
  }
  REQUIRE(store.append_samples(id, rows).has_value());
  auto got = store.get_samples(id, 0, 0, 10);
  REQUIRE(got->size() == 4);
  CHECK(got->at(1).t1_y_c == 32.0);
  CHECK(got->at(1).t2_z_c == 35.0);
  CHECK(std::isnan(got->at(2).t2_z_c));
  CHECK(std::isnan(store.get_samples(id, 1, 0, 10)->at(0).t1_y_c));  // the one-axis unit: NULL
  Raw raw(tmp / "a.db");
  CHECK(raw.integer("SELECT count(*) FROM sample_view WHERE t1_y_c IS NOT NULL") == 4);
  CHECK(raw.integer("SELECT count(*) FROM samples WHERE unit_index = 1 AND t1_y_c IS NULL AND t2_z_c IS NULL") == 4);

  // Exported: the four columns, x's being t1_c, t2_c; the one-axis unit without them.
  auto x = store.export_run(id, 0);
  REQUIRE(x.has_value());
  REQUIRE(x->has_axis_thermistors());
  CHECK(x->axis_t1_c[0] == x->t1_c);
  CHECK(x->axis_t1_c[1] == std::vector<double>{31.0, 32.0, 33.0, 34.0});
  const std::string text = to_csv(*x);
  CHECK_THAT(text, Contains("gyro_y_dph,gyro_z_dph,t1_y_c,t2_y_c,t1_z_c,t2_z_c\n"));
  CHECK_FALSE(store.export_run(id, 1)->has_axis_thermistors());
  CHECK(to_csv(*store.export_run(id, 1)).find("t1_y_c") == std::string::npos);

  // Imported again (the refusal of earlier versions gone): the same file comes back.
  CsvOptions o;
  o.source_name = "x.csv";
  auto back = parse_csv(text, o);
  REQUIRE(back.has_value());
  REQUIRE(back->has_axis_thermistors());
  ImportOptions io;
  io.serial = "FOG-001";
  auto again = store.import_run(*back, io);
  INFO((again ? std::string() : again.error().message));
  REQUIRE(again.has_value());
  auto x2 = store.export_run(*again, 0);
  REQUIRE(x2.has_value());
  CHECK(to_csv(*x2) == text);

  // Per-axis thermistors without y and z outputs, or a short column: refused, named, nothing stored.
  const auto runs_before = store.list_runs();
  model::RunData no_axes = *back;
  no_axes.gyro_y_dph.clear();
  no_axes.gyro_z_dph.clear();
  auto refused = store.import_run(no_axes, io);
  REQUIRE_FALSE(refused.has_value());
  CHECK_THAT(refused.error().message, Contains("per-axis thermistors") && Contains("gyro_y_dph"));
  model::RunData short_z = *back;
  short_z.axis_t2_c[2].pop_back();
  refused = store.import_run(short_z, io);
  REQUIRE_FALSE(refused.has_value());
  CHECK_THAT(refused.error().message, Contains("t2_z_c has 3 values but time_s has 4"));
  CHECK(store.list_runs()->size() == runs_before->size());
}

TEST_CASE("store axes: a version 14 file upgrades to per-axis thermistors with its rows unchanged", "[store][axes][schema]") {
  TempDir tmp;
  const auto path = tmp / "old.db";
  std::int64_t id = 0;
  {
    auto store = open_ok(path);
    id = three_axis_run(store);
  }
  {
    Raw raw(path);
    raw.exec("DROP VIEW sample_view");
    for (const char* c : {"t1_y_c", "t2_y_c", "t1_z_c", "t2_z_c"}) raw.exec(std::string("ALTER TABLE samples DROP COLUMN ") + c);
    raw.exec("CREATE VIEW sample_view AS SELECT * FROM samples");
    raw.exec("PRAGMA user_version = 14");
  }
  auto store = open_ok(path);
  {
    Raw raw(path);
    CHECK(raw.integer("PRAGMA user_version") == Store::current_schema_version());
    CHECK(raw.integer("SELECT count(*) FROM sample_view WHERE t1_y_c IS NULL") == 8);
  }
  auto x = store.export_run(id, 0);
  REQUIRE(x.has_value());
  CHECK(x->has_axes());
  CHECK_FALSE(x->has_axis_thermistors());  // recorded before: the axes shared t1_c, t2_c
  CHECK(x->gyro_y_dph[1] == 101.0);
}

TEST_CASE("csv axes: gyro_y_dph without gyro_z_dph is refused, naming the missing column", "[csv][axes]") {
  CsvOptions o;
  o.source_name = "half.csv";
  auto r = parse_csv("time_s,gyro_dph,t1_c,t2_c,gyro_y_dph\n0,1,2,3,4\n1,1,2,3,4\n", o);
  REQUIRE_FALSE(r.has_value());
  CHECK(r.error().code == CsvErrc::missing_column);
  CHECK_THAT(r.error().message, Contains("'gyro_z_dph' not found"));
  CHECK_THAT(r.error().message, Contains("half.csv"));
}

TEST_CASE("csv axes: an empty y or z cell on a row not flagged missing is an error", "[csv][axes]") {
  CsvOptions o;
  o.source_name = "gap.csv";
  auto r = parse_csv("time_s,gyro_dph,t1_c,t2_c,flags,gyro_y_dph,gyro_z_dph\n0,1,2,3,0,4,5\n1,1,2,3,0,,5\n", o);
  REQUIRE_FALSE(r.has_value());
  CHECK(r.error().code == CsvErrc::not_a_number);
  CHECK(r.error().line == 3);
  CHECK(r.error().column == 6);
}

TEST_CASE("csv axes: per-axis thermistors come four together beside y and z, and resample with the run", "[csv][axes][cross_axis]") {
  CsvOptions o;
  o.source_name = "cross.csv";
  // One of the four: refused, naming the three absent.
  auto r = parse_csv("time_s,gyro_dph,t1_c,t2_c,gyro_y_dph,gyro_z_dph,t1_y_c\n0,1,2,3,4,5,6\n1,1,2,3,4,5,6\n", o);
  REQUIRE_FALSE(r.has_value());
  CHECK(r.error().code == CsvErrc::missing_column);
  CHECK_THAT(r.error().message, Contains("'t2_y_c', 't1_z_c', 't2_z_c' not found"));
  // All four without the y and z outputs: refused, naming those.
  r = parse_csv("time_s,gyro_dph,t1_c,t2_c,t1_y_c,t2_y_c,t1_z_c,t2_z_c\n0,1,2,3,4,5,6,7\n1,1,2,3,4,5,6,7\n", o);
  REQUIRE_FALSE(r.has_value());
  CHECK_THAT(r.error().message, Contains("'gyro_y_dph', 'gyro_z_dph' not found"));
  // Whole: x's are t1_c, t2_c; read and resampled to 0.5 s, each column interpolated with the run.
  const std::string text =
      "time_s,gyro_dph,t1_c,t2_c,gyro_y_dph,gyro_z_dph,t1_y_c,t2_y_c,t1_z_c,t2_z_c\n"
      "0,1,20,21,4,5,22,23,24,25\n1,1,21,22,4,5,24,25,26,27\n2,1,22,23,4,5,26,27,28,29\n";
  auto ok = parse_csv(text, o);
  REQUIRE(ok);
  REQUIRE(ok->has_axis_thermistors());
  CHECK(ok->axis_t1_c[0] == std::vector<double>{20, 21, 22});
  CHECK(ok->axis_t2_c[1] == std::vector<double>{23, 25, 27});
  CHECK(ok->axis_t1_c[2] == std::vector<double>{24, 26, 28});
  CsvOptions half = o;
  half.resample_s = 0.5;
  auto rs = parse_csv(text, half);
  REQUIRE(rs);
  REQUIRE(rs->size() == 5);
  CHECK(rs->axis_t1_c[1][1] == Approx(23.0));
  CHECK(rs->axis_t2_c[2][3] == Approx(28.0));
  CHECK(rs->axis_t1_c[0] == rs->t1_c);
  // Written back: the same four columns after gyro_z_dph.
  CHECK(to_csv(*ok).rfind("time_s,gyro_dph,t1_c,t2_c,gyro_y_dph,gyro_z_dph,t1_y_c,t2_y_c,t1_z_c,t2_z_c\n", 0) == 0);
}
