// The plan limit sf_tc_ppm_per_c and the certificate's scale factor (issue 29, point 2), in
// process: a station with a rate table (no I/O: the table's reading is given each tick, as in
// station_rate_table_test.cpp) runs a plan's fit step whose profile has a rate sequence on
// three temperature plateaus; the synthetic bench's two gyros see the commanded rate through
// sim::ScaleFactorTruth with true temperature sensitivities of 4 and 16 ppm/degC, so a limit of
// 10 ppm/degC passes the first and fails the second. A limit on a plan without rate steps is
// refused naming its line.
#include "fixture.hpp"

#include <filesystem>
#include <fstream>
#include <unistd.h>

#include "fogbench/daemon/plan_runner.hpp"
#include "fogbench/signing/certificate.hpp"
#include "fogbench/sim/scale_factor.hpp"

using namespace fogbench;
using namespace fogbench::daemon;
using namespace fogbench::daemon::test;
using nlohmann::json;

namespace {

// A hold with the rate sequence (+-10, +-60 deg/s, 20 s each, then at rest), after a hold long
// enough for the coil (tau 240 s) to reach the plateau. 60 deg/s is 2.2e5 deg/h, beyond the drift
// bench's gyro bound (kGyroMaxAbsDph, 1e5 deg/h): on a table the bound grows by the run's largest
// rate, and those seconds are kept (they were flagged out of range and the fit failed).
std::string spin_plateau() {
  return "hold 100 s\nrate 10 dps for 20 s\nrate -10 dps for 20 s\nrate 60 dps for 20 s\nrate -60 dps for 20 s\n";
}

struct Rig {
  std::filesystem::path dir;
  storage::Store store = memory_store();
  std::unique_ptr<Station> st;
  std::unique_ptr<PlanRunner> runner;
  SyntheticBench bench{2};
  std::vector<sim::ScaleFactorTruth> truth{2};
  double clock_s = 0.0;
  double sp_c = 20.0;
  double rate_dps = 0.0;  // the table's command of the previous second: the gyros see it now

  Rig() {
    dir = std::filesystem::temp_directory_path() / ("fogbench-plan-sf-" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir);
    // The drift fit (the fit step's analysis) needs an opening hold at rest.
    std::ofstream(dir / "spin.profile") << "setpoint 20 C\nhold 2 min\n" + spin_plateau() + "ramp to 30 C at 2 C/min\nhold 15 min\n" +
                                               spin_plateau() + "ramp to 40 C at 2 C/min\nhold 15 min\n" + spin_plateau();
    std::ofstream(dir / "still.profile") << "setpoint 20 C\nhold 10 min\nramp to 25 C at 1 C/min\nhold 5 min\n";
    // The sequence's 60 deg/s needs a coarser scale than the golden units' (fixture.hpp).
    auto c = golden_config({{"profile_dir", dir.string()},
                            {"drivers", golden_units_at_scale(1e-3)},
                            {"rate_table", {{"kind", "acutrol"}, {"link", {{"transport", "tcp"}, {"host", "127.0.0.1"}, {"port", 9888}}}}}});
    st = std::make_unique<Station>(std::move(c), store, 1.0, [] { return std::string("2026-01-01T00:00:00Z"); });
    runner = std::make_unique<PlanRunner>(*st, st->store());
    st->add_tick_listener(runner.get());
    truth[0].tc_ppm_per_c = 4.0;
    truth[1].tc_ppm_per_c = 16.0;
    for (auto& t : truth) t.nl_ppm = 30.0, t.asymmetry_ppm = 20.0;
  }
  ~Rig() {
    std::error_code ec;
    std::filesystem::remove_all(dir, ec);
  }
  void tick() {
    TickInput in = bench.step(sp_c);
    in.rate_table = RateTableReading{};  // the table answers, no fault
    for (std::size_t i = 0; i < in.units.size(); ++i)
      *in.units[i].gyro_dph += 3600.0 * sim::indicated_rate_dps(truth[i], rate_dps, *in.units[i].t1_c, 0.0);
    const TickOutput out = st->tick(clock_s, in);
    sp_c = out.setpoint_c;
    rate_dps = out.rate_dps;
    clock_s += 1.0;
  }
  json plan_status(std::int64_t id) { return runner->status(id).value(); }
  // Starts the plan for `units`, ticks until it ends or `max_ticks` seconds pass, and gives its
  // status.
  json run_plan(const std::string& text, const std::string& source, const std::vector<std::string>& units, int max_ticks) {
    auto started = runner->start(text, source, units, PlanTrace{}, json{{"cmd", "plan.start"}});
    INFO((started ? std::string() : started.error().message));
    REQUIRE(started.has_value());
    const auto plan_id = (*started)["plan_id"].get<std::int64_t>();
    for (int k = 0; k < max_ticks && plan_status(plan_id)["state"] == "running"; ++k) tick();
    return plan_status(plan_id);
  }
};

const json* measurement(const json& unit, const std::string& name) {
  for (const auto& m : unit["measurements"])
    if (m["measurement"] == name) return &m;
  return nullptr;
}

}  // namespace

TEST_CASE("plan limit sf_tc_ppm_per_c: |tc| of the mock gyros (4 and 16 ppm/degC) against 10 passes one and fails the other, and the certificate carries the scale factor") {
  Rig r;
  const json s = r.run_plan("plan sf\nstep spin fit\nlimit sf_tc_ppm_per_c < 10 ppm/degC\n", "sf.plan", {"FOG-0001", "FOG-0002"}, 6000);
  INFO(s.dump(1));
  REQUIRE(s["state"] != "running");
  const json& units = s["progress"]["units"];
  REQUIRE(units.size() == 2);
  const json* good = measurement(units[0], "sf_tc_ppm_per_c");
  const json* bad = measurement(units[1], "sf_tc_ppm_per_c");
  REQUIRE(good);
  REQUIRE(bad);
  CHECK((*good)["unit"] == "ppm/degC");
  CHECK((*good)["limit"] == "sf_tc_ppm_per_c < 10 ppm/degC");
  CHECK((*good)["value"].get<double>() == Approx(4.0).margin(0.5));
  CHECK((*good)["met"] == true);
  CHECK_THAT((*good)["note"].get<std::string>(), Catch::Contains("ppm/degC (1 sigma) over 3 plateaus"));
  CHECK((*bad)["value"].get<double>() == Approx(16.0).margin(0.5));
  CHECK((*bad)["met"] == false);
  CHECK(units[0]["verdict"] != "fail");
  CHECK(units[1]["verdict"] == "fail");
  CHECK_THAT(units[1]["reasons"][0].get<std::string>(),
             Catch::Contains("sf_tc_ppm_per_c = 16") && Catch::Contains("limit sf_tc_ppm_per_c < 10 ppm/degC (line 3)"));

  // The certificate of each unit carries its fit run's scale factor, and its signature holds.
  for (const auto& [serial, tc] : {std::pair{"FOG-0001", 4.0}, std::pair{"FOG-0002", 16.0}}) {
    INFO(serial);
    auto certs = r.store.list_certificates(serial);
    REQUIRE(certs.has_value());
    REQUIRE_FALSE(certs->empty());
    const json cert = json::parse(certs->back().json);
    REQUIRE(cert.contains("scale_factor"));
    REQUIRE(cert["scale_factor"].size() == 1);
    const json& sf = cert["scale_factor"][0];
    CHECK(sf["role"] == "fit");
    CHECK(sf["sf0"].get<double>() == Approx(1.0).margin(1e-4));
    CHECK(sf["tc_ppm_per_c"]["value"].get<double>() == Approx(tc).margin(0.5));
    CHECK(sf["tc_ppm_per_c"]["sigma"].get<double>() >= 0.0);
    CHECK(sf["model_form"]["k1_ppm_per_c"]["value"].get<double>() == Approx(tc).margin(0.5));
    REQUIRE(sf["plateaus"].size() == 3);
    for (const auto& p : sf["plateaus"]) {
      CHECK(p["asymmetry_ppm"].get<double>() == Approx(20.0).margin(3.0));
      CHECK(p["nonlinearity_ppm"].is_number());
    }
    CHECK(cert["sha256"] == signing::content_sha256(cert));
  }
}

TEST_CASE("plan limit sf_tc_ppm_per_c on a plan whose fit and verify steps have no rate steps is refused naming the limit's line") {
  Rig r;
  auto v = r.runner->validate("plan still\nstep still fit\nstep spin soak\nlimit sf_tc_ppm_per_c < 20\n", "still.plan", {}, {});
  REQUIRE_FALSE(v.has_value());
  CHECK(v.error().code == ErrorCode::bad_request);
  CHECK_THAT(v.error().message,
             Catch::StartsWith("still.plan:4: limit sf_tc_ppm_per_c < 20 ppm/degC: no fit or verify step of this plan has a profile with rate steps"));
  // A rate profile in a fit step: accepted.
  CHECK(r.runner->validate("plan spin\nstep still fit\nstep spin verify\nlimit sf_tc_ppm_per_c < 20\n", "spin.plan", {}, {})
            .has_value());
}

TEST_CASE("plan limit sf_tc_ppm_per_c: a step with rate steps whose fit fails (one plateau) fails the limit with the reason") {
  Rig r;
  std::ofstream(r.dir / "one.profile") << "setpoint 20 C\nhold 2 min\n" + spin_plateau() + "ramp to 25 C at 1 C/min\nhold 8 min\n";
  const json s = r.run_plan("plan one\nstep one fit\nlimit sf_tc_ppm_per_c < 1000 continue\n", "one.plan", {"FOG-0001"}, 3000);
  INFO(s.dump(1));
  const json* m = measurement(s["progress"]["units"][0], "sf_tc_ppm_per_c");
  REQUIRE(m);
  CHECK((*m)["value"].is_null());
  CHECK((*m)["met"] == false);
  CHECK_THAT((*m)["note"].get<std::string>(), Catch::Contains("not identified") && Catch::Contains("plateaus"));
  CHECK(s["progress"]["units"][0]["marginal"] == true);
  CHECK_THAT(s["progress"]["units"][0]["reasons"][0].get<std::string>(),
             Catch::Contains("sf_tc_ppm_per_c = not measured (the temperature sensitivity is not identified"));
}

TEST_CASE("plan limits sf_nonlinearity_ppm and sf_asymmetry_ppm: the worst plateau of each gyro against its limit, with the plateau named") {
  Rig r;
  // The first gyro as above (cubic nonlinearity 30 ppm, asymmetry 20 ppm); the second with 100
  // times the nonlinearity and 400 ppm of asymmetry. The measured nonlinearity is the line's
  // largest residual over +-10 and +-60 deg/s, of full scale: about 5 and 110 ppm.
  r.truth[1].nl_ppm = 3000.0;
  r.truth[1].asymmetry_ppm = 400.0;
  const json s = r.run_plan("plan sf\nstep spin fit\nlimit sf_asymmetry_ppm < 100 ppm\nlimit sf_nonlinearity_ppm < 50 continue\n", "sf.plan",
                            {"FOG-0001", "FOG-0002"}, 6000);
  INFO(s.dump(1));
  REQUIRE(s["state"] != "running");
  const json& units = s["progress"]["units"];
  REQUIRE(units.size() == 2);
  const json* asym0 = measurement(units[0], "sf_asymmetry_ppm");
  const json* asym1 = measurement(units[1], "sf_asymmetry_ppm");
  const json* nl0 = measurement(units[0], "sf_nonlinearity_ppm");
  const json* nl1 = measurement(units[1], "sf_nonlinearity_ppm");
  REQUIRE(asym0);
  REQUIRE(asym1);
  REQUIRE(nl0);
  REQUIRE(nl1);
  CHECK((*asym0)["unit"] == "ppm");
  CHECK((*asym0)["value"].get<double>() == Approx(20.0).margin(3.0));
  CHECK((*asym0)["met"] == true);
  CHECK((*asym1)["value"].get<double>() == Approx(400.0).margin(10.0));
  CHECK((*asym1)["met"] == false);
  CHECK_THAT((*asym1)["note"].get<std::string>(), Catch::Contains("the worst of 3 plateaus") && Catch::Contains("degC)"));
  CHECK((*nl0)["value"].get<double>() < 50.0);
  CHECK((*nl1)["value"].get<double>() > 50.0);
  CHECK((*nl1)["met"] == false);
  CHECK_THAT((*nl1)["note"].get<std::string>(), Catch::Contains("the worst of 3 plateaus: plateau "));
  CHECK(units[0]["verdict"] == "pass");
  CHECK(units[1]["verdict"] == "fail");
  CHECK_THAT(units[1]["reasons"][0].get<std::string>(),
             Catch::Contains("sf_asymmetry_ppm = 4") && Catch::Contains("limit sf_asymmetry_ppm < 100 ppm (line 3)"));
}
