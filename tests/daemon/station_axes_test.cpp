// Three-axis units in the station (issue 29 point 3, the daemon): a real GyroBus fed fake frames
// in-process (no transport read: GyroBus::route), its samples turned into the second's readings
// by the acquisition's own fill_gyro_readings, and the station storing every axis. An axis that
// goes silent while the others send is flagged missing each second and said once as an event
// naming the unit, the axis and the time; a one-axis unit beside it records as before.
#include <cmath>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "../../daemon/src/acquisition.hpp"
#include "../../daemon/src/run_reads.hpp"
#include "fixture.hpp"
#include "fogbench/drivers/can_frame.hpp"
#include "fogbench/drivers/gyro_bus.hpp"
#include "fogbench/model/run.hpp"

using namespace fogbench;
using namespace fogbench::daemon;
using namespace fogbench::daemon::test;
using nlohmann::json;

namespace {

constexpr std::uint16_t kBase = 0x110;   // unit 0: three axes on 0x110, 0x111, 0x112
constexpr std::uint16_t kSingle = 0x120; // unit 1: one axis
constexpr int kFramesPerSecond = 10;
constexpr double kScaleDphPerCount = 0.0001;  // the golden configuration's

// Never read: the test routes its frames straight into the bus.
class NoTransport final : public drivers::CanTransport {
 public:
  int fd() const noexcept override { return -1; }
  drivers::Result<std::size_t> read(std::vector<::can_frame>& out) override {
    out.clear();
    return std::size_t{0};
  }
  std::uint64_t malformed() const noexcept override { return 0; }
  std::string describe() const override { return "no transport (test)"; }
};

DaemonConfig three_axis_config() {
  json j = golden_config_json();
  j["drivers"]["units"][0]["gyro"]["node_id"] = kBase;
  j["drivers"]["units"][0]["gyro"]["axes"] = 3;
  j["drivers"]["units"][1]["gyro"]["node_id"] = kSingle;
  auto c = parse_daemon_config(j, golden_dir());
  REQUIRE(c.has_value());
  return *c;
}

// Each axis k of unit 0 reads (k + 1) * 100 deg/h + the second, unit 1 reads -5 deg/h; axis
// `silent_axis` of unit 0 sends nothing in seconds [silent_from, silent_to).
struct AxisBench {
  drivers::GyroBus bus;
  std::uint8_t seq[3] = {0, 0, 0};
  std::uint8_t seq_single = 0;
  int second = 0;
  int silent_axis = 2;
  int silent_from = 10, silent_to = 15;
  // Axis `saturated_axis` of unit 0 sends counts at the int32 limit in [saturated_from,
  // saturated_to): a rate beyond what its scale carries (none by default).
  int saturated_axis = -1;
  int saturated_from = 0, saturated_to = 0;

  explicit AxisBench(const DaemonConfig& c)
      : bus(std::make_unique<NoTransport>(),
            std::vector<drivers::GyroChannelConfig>{c.drivers.units[0].gyro, c.drivers.units[1].gyro}) {}

  static double axis_dph(int axis, int second) { return (axis + 1) * 100.0 + second; }

  void fill(TickInput& in) {
    const bool silence = second >= silent_from && second < silent_to;
    for (int f = 0; f < kFramesPerSecond; ++f) {
      for (int k = 0; k < 3; ++k) {
        if (silence && k == silent_axis) continue;
        const bool at_limit = k == saturated_axis && second >= saturated_from && second < saturated_to;
        const auto counts = at_limit ? std::numeric_limits<std::int32_t>::max()
                                     : static_cast<std::int32_t>(std::lround(axis_dph(k, second) / kScaleDphPerCount));
        bus.route(drivers::can::encode({static_cast<std::uint16_t>(kBase + k), counts, seq[k]++, drivers::can::status::valid}));
      }
      bus.route(drivers::can::encode(
          {kSingle, static_cast<std::int32_t>(std::lround(-5.0 / kScaleDphPerCount)), seq_single++, drivers::can::status::valid}));
    }
    fill_gyro_readings(bus.close_samples(), in.units);
    ++second;
  }
};

// A run of `ticks` seconds on the bus's gyros, from clock 100 s (`before_tick(n)`, when given,
// first each second), then aborted and ticked once more, as a run's end.
void run_seconds(Station& st, SyntheticBench& thermal, AxisBench& gyros, int ticks,
                 const std::function<void(int)>& before_tick = {}) {
  double clock_s = 100.0;
  double sp = st.status()["setpoint_c"].get<double>();
  for (int n = 0; n < ticks; ++n) {
    if (before_tick) before_tick(n);
    TickInput in = thermal.step(sp);
    for (auto& u : in.units) u.gyro_dph.reset();  // the gyros are the bus's
    gyros.fill(in);
    sp = st.tick(clock_s, in).setpoint_c;
    clock_s += 1.0;
  }
  REQUIRE(st.abort_run("test over", {{"cmd", "run.abort"}}).has_value());
  st.tick(clock_s, thermal.step(sp));
}

// The run's gyro_axis fault events of `kind` ("silent", "saturated"): their details, each
// checked to carry the event's own time (s).
std::vector<json> axis_events(const storage::RunDetail& detail, const std::string& kind) {
  std::vector<json> out;
  for (const auto& e : detail.events) {
    if (e.kind != storage::EventKind::fault) continue;
    json d = json::parse(e.detail_json);
    if (d.value("gyro_axis", "") != kind) continue;
    REQUIRE(e.t_s.has_value());
    CHECK(d["t_s"] == *e.t_s);
    out.push_back(std::move(d));
  }
  return out;
}

}  // namespace

TEST_CASE("station: a three-axis unit's y and z are stored per second, a silent axis flagged and said once") {
  const DaemonConfig config = three_axis_config();
  REQUIRE(config.drivers.units[0].gyro.axes == 3);
  auto store = memory_store();
  Station st(config, store, 1.0, [] { return std::string("2026-01-01T00:00:00Z"); });
  std::vector<json> published;
  st.set_publisher([&](const json& m) { published.push_back(m); });
  SyntheticBench thermal(2);
  AxisBench gyros(config);

  auto id = st.start_run("short", {"FOG-0001", "FOG-0002"}, storage::Purpose::fit, {{"cmd", "run.start"}});
  REQUIRE(id.has_value());
  constexpr int kTicks = 30;
  run_seconds(st, thermal, gyros, kTicks);

  auto detail = store.get_run(*id);
  REQUIRE(detail.has_value());
  REQUIRE(detail->run.units.size() == 2);
  CHECK(detail->run.units[0].axes == 3);
  CHECK(detail->run.units[1].axes == 1);

  auto rows = store.get_samples(*id, 0, 0, kTicks);
  REQUIRE(rows.has_value());
  REQUIRE(rows->size() == kTicks);
  for (int s = 0; s < kTicks; ++s) {
    const storage::SampleRow& r = rows->at(static_cast<std::size_t>(s));
    INFO("second " << s);
    CHECK(r.t_s == s);
    CHECK(r.gyro_dph == Approx(AxisBench::axis_dph(0, s)).margin(1e-9));
    CHECK(r.gyro_y_dph == Approx(AxisBench::axis_dph(1, s)).margin(1e-9));
    if (s >= 10 && s < 15) {
      CHECK(std::isnan(r.gyro_z_dph));
      CHECK((r.flags & model::flag::missing) != 0);
    } else {
      CHECK(r.gyro_z_dph == Approx(AxisBench::axis_dph(2, s)).margin(1e-9));
      CHECK((r.flags & model::flag::missing) == 0);
    }
    CHECK((r.flags & model::flag::frames_lost) == 0);  // z's counter goes on where it stopped: nothing lost
  }

  // The one-axis unit beside it: no y, no z, never flagged for them.
  auto single = store.get_samples(*id, 1, 0, kTicks);
  REQUIRE(single.has_value());
  REQUIRE(single->size() == kTicks);
  for (const auto& r : *single) {
    CHECK(r.gyro_dph == Approx(-5.0).margin(1e-9));
    CHECK(std::isnan(r.gyro_y_dph));
    CHECK(std::isnan(r.gyro_z_dph));
    CHECK((r.flags & model::flag::missing) == 0);
  }

  // The silence is one event, at its first second, naming unit, serial, axis and CAN id.
  const auto silent = axis_events(*detail, "silent");
  REQUIRE(silent.size() == 1);
  CHECK(silent[0]["unit"] == 0);
  CHECK(silent[0]["serial"] == "FOG-0001");
  CHECK(silent[0]["axis"] == "z");
  CHECK(silent[0]["can_id"] == kBase + 2);
  CHECK(silent[0]["t_s"] == 10.0);

  // Pushed live: the three-axis unit's samples with y and z (z null while silent), the other's
  // without the fields.
  int pushed0 = 0, pushed1 = 0;
  for (const auto& m : published) {
    if (m.value("type", "") != "sample") continue;
    const double t = m["t_s"].get<double>();
    if (m["unit"] == 0) {
      ++pushed0;
      REQUIRE(m.contains("gyro_y_dph"));
      CHECK(m["gyro_y_dph"].get<double>() == Approx(AxisBench::axis_dph(1, static_cast<int>(t))).margin(1e-9));
      CHECK(m["gyro_z_dph"].is_null() == (t >= 10 && t < 15));
    } else {
      ++pushed1;
      CHECK_FALSE(m.contains("gyro_y_dph"));
      CHECK_FALSE(m.contains("gyro_z_dph"));
    }
  }
  CHECK(pushed0 == kTicks);
  CHECK(pushed1 == kTicks);

  // run.samples: the same, from the store.
  auto page0 = run_samples(store, *id, {{"unit", 0}}, 0, 100);
  REQUIRE(page0.has_value());
  REQUIRE((*page0)["samples"].size() == kTicks);
  CHECK((*page0)["samples"][3]["gyro_z_dph"].get<double>() == Approx(AxisBench::axis_dph(2, 3)).margin(1e-9));
  CHECK((*page0)["samples"][12]["gyro_z_dph"].is_null());
  auto page1 = run_samples(store, *id, {{"unit", 1}}, 0, 100);
  REQUIRE(page1.has_value());
  CHECK_FALSE((*page1)["samples"][0].contains("gyro_y_dph"));
}

TEST_CASE("station: a gyro axis at its int32 count limit is flagged out_of_range and said once, not stored silently") {
  const DaemonConfig config = three_axis_config();
  auto store = memory_store();
  Station st(config, store, 1.0, [] { return std::string("2026-01-01T00:00:00Z"); });
  SyntheticBench thermal(2);
  AxisBench gyros(config);
  gyros.silent_from = gyros.silent_to = 0;  // no silence here
  gyros.saturated_axis = 1;                 // y
  gyros.saturated_from = 8;
  gyros.saturated_to = 12;
  auto id = st.start_run("short", {"FOG-0001", "FOG-0002"}, storage::Purpose::fit, {{"cmd", "run.start"}});
  REQUIRE(id.has_value());
  constexpr int kTicks = 20;
  run_seconds(st, thermal, gyros, kTicks);

  auto rows = store.get_samples(*id, 0, 0, kTicks);
  REQUIRE(rows.has_value());
  REQUIRE(rows->size() == kTicks);
  for (int s = 0; s < kTicks; ++s) {
    const storage::SampleRow& r = rows->at(static_cast<std::size_t>(s));
    INFO("second " << s);
    const bool clipped = s >= 8 && s < 12;
    CHECK(((r.flags & model::flag::out_of_range) != 0) == clipped);
    // The clipped value is kept (flagged): INT32_MAX counts x 1e-4 deg/h = 214748.3647 deg/h.
    if (clipped) CHECK(r.gyro_y_dph == Approx(2147483647.0 * kScaleDphPerCount).epsilon(1e-12));
    CHECK(r.gyro_dph == Approx(AxisBench::axis_dph(0, s)).margin(1e-9));  // x unaffected
  }
  auto single = store.get_samples(*id, 1, 0, kTicks);
  REQUIRE(single.has_value());
  for (const auto& r : *single) CHECK((r.flags & model::flag::out_of_range) == 0);

  auto detail = store.get_run(*id);
  REQUIRE(detail.has_value());
  const auto saturated = axis_events(*detail, "saturated");
  REQUIRE(saturated.size() == 1);  // once per axis and run, at its first second
  CHECK(saturated[0]["unit"] == 0);
  CHECK(saturated[0]["serial"] == "FOG-0001");
  CHECK(saturated[0]["axis"] == "y");
  CHECK(saturated[0]["can_id"] == kBase + 1);
  CHECK(saturated[0]["t_s"] == 8.0);
  // 1e-4 deg/h per count holds 2147483647 x 1e-4 / 3600 = 59.65 deg/s.
  CHECK(saturated[0]["holds_dps"].get<double>() == Approx(59.652).margin(1e-3));
  const std::string reason = saturated[0]["reason"];
  CHECK(reason.find("10 of 10 frames on CAN id " + std::to_string(kBase + 1) + " at the int32 count limit") == 0);
}

TEST_CASE("station: a configuration reloaded mid-run does not change the running run's axes") {
  const DaemonConfig config = three_axis_config();
  auto store = memory_store();
  Station st(config, store, 1.0, [] { return std::string("2026-01-01T00:00:00Z"); });
  std::vector<json> published;
  st.set_publisher([&](const json& m) { published.push_back(m); });
  SyntheticBench thermal(2);
  AxisBench gyros(config);  // unit 0's bus stays three-axis: the devices are opened at start
  gyros.silent_from = 15;   // z silent in seconds 15..19, after the reload
  gyros.silent_to = 20;
  auto id = st.start_run("short", {"FOG-0001", "FOG-0002"}, storage::Purpose::fit, {{"cmd", "run.start"}});
  REQUIRE(id.has_value());
  // The reloaded configuration says unit 0 is one-axis.
  DaemonConfig one_axis = config;
  one_axis.drivers.units[0].gyro.axes = 1;
  constexpr int kTicks = 20;
  run_seconds(st, thermal, gyros, kTicks, [&](int n) {
    if (n == 5) st.reload_config(one_axis);
  });

  // Every pushed sample of unit 0, before and after the reload, is the three-axis unit's.
  int pushed0 = 0;
  for (const auto& m : published) {
    if (m.value("type", "") != "sample" || m["unit"] != 0) continue;
    ++pushed0;
    INFO("t_s " << m["t_s"]);
    REQUIRE(m.contains("gyro_y_dph"));
    CHECK(m["gyro_y_dph"].get<double>() == Approx(AxisBench::axis_dph(1, static_cast<int>(m["t_s"].get<double>()))).margin(1e-9));
  }
  CHECK(pushed0 == kTicks);
  // The silence after the reload is still a three-axis unit's silent axis.
  auto detail = store.get_run(*id);
  REQUIRE(detail.has_value());
  const auto silent = axis_events(*detail, "silent");
  REQUIRE(silent.size() == 1);
  CHECK(silent[0]["t_s"] == 15.0);
}
