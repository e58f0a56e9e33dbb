// The rate table live (issue 29): the real fogbenchd configured with `rate_table` against the real
// fogbench-sim --rate-table-port (its ACUTROL table, docs/mock-bench.md "Rate table"), whose gyros
// see the table's rate through the bench's true scale factor (the ready line's
// scale_factor_truth). A profile's rate steps at a plateau are commanded and stored second by
// second, and the exported CSV gives `fogctl scale-factor` the true scale factor back; a fault the
// table reports and its link lost abort the run naming the table, with the chamber at its safe
// setpoint, the table brought to rest and the samples stored kept. Every wait has a deadline.
#include "live_bench.hpp"

#include <sys/wait.h>

#include <cmath>

using namespace fogbench::daemon::test;
using namespace fogbench::daemon::test::live;
using nlohmann::json;
using namespace std::chrono_literals;

namespace {

// A plateau at the bench's start temperature with a rate sequence: +10 deg/s for 40 s, -10 deg/s
// for 40 s, then 40 s at rest (the zero-rate step the plateau's bias comes from).
constexpr double kStepS = 40.0;
const char* const kSpin = "setpoint 20 C\nhold 120 s\nrate 10 dps for 40 s\nrate -10 dps for 40 s\n";
// A long sequence for the fault cases, so that the fault lands while the table turns.
const char* const kLongSpin = "setpoint 20 C\nhold 2 h\nrate 10 dps for 2 h\n";

double schedule_dps(double into_hold_s) {
  if (into_hold_s < kStepS) return 10.0;
  if (into_hold_s < 2 * kStepS) return -10.0;
  return 0.0;
}

std::string slurp(const std::filesystem::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

struct Out {
  int code = -1;
  std::string out, err;
};

// fogctl with `args` (shell words, quoted by the caller) in the bench's directory.
Out fogctl(const LiveBench& bench, const std::string& args) {
  const auto out = bench.dir / "fogctl.out", err = bench.dir / "fogctl.err";
  const std::string cmd = "cd '" + bench.dir.string() + "' && env -u FOGBENCH_TOKEN '" + (kBin / "fogctl").string() + "' " +
                          args + " >'" + out.string() + "' 2>'" + err.string() + "'";
  const int st = std::system(cmd.c_str());
  Out o;
  o.code = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
  o.out = slurp(out);
  o.err = slurp(err);
  return o;
}

json all_samples(LineClient& c, std::int64_t run) {
  auto page = c.call({{"cmd", "run.samples"}, {"run_id", run}, {"limit", 10000}});
  INFO(page.dump());
  REQUIRE(code_of(page) == "ok");
  return page["result"]["samples"];
}

// The sim's table rate (its status reply's rate_table.rate_dps), deg/s; NaN without a reply.
double sim_table_dps(LiveBench& bench) {
  auto s = bench.sim_command({{"cmd", "status"}});
  if (!s.is_object() || !s.contains("rate_table")) return std::nan("");
  return s["rate_table"]["rate_dps"].get<double>();
}

// Waits until a stored sample of the run has the table commanded to 10 deg/s; that sample count.
std::size_t wait_turning(LiveBench& bench, LineClient& c, std::int64_t run) {
  const auto deadline = SteadyClock::now() + 120s;
  while (SteadyClock::now() < deadline) {
    auto page = c.call({{"cmd", "run.samples"}, {"run_id", run}, {"limit", 10000}});
    if (code_of(page) == "ok") {
      std::size_t turning = 0;
      for (const auto& s : page["result"]["samples"])
        if (s.contains("rate_in_dps") && s["rate_in_dps"] == 10.0) ++turning;
      // A few seconds in, and the sim's table seen at the rate.
      if (turning >= 5 && std::abs(sim_table_dps(bench) - 10.0) < 0.01) return page["result"]["samples"].size();
    }
    std::this_thread::sleep_for(100ms);
  }
  FAIL("the table never turned at 10 deg/s (fogbenchd log in " << (bench.dir / "fogbenchd.log") << ")");
  return 0;
}

// The sim's table at rest within `timeout`.
bool table_comes_to_rest(LiveBench& bench, std::chrono::seconds timeout) {
  const auto deadline = SteadyClock::now() + timeout;
  while (SteadyClock::now() < deadline) {
    if (std::abs(sim_table_dps(bench)) < 1e-6) return true;
    std::this_thread::sleep_for(100ms);
  }
  return false;
}

}  // namespace

TEST_CASE("e2e rate table: the stored rate follows the profile's rate steps and fogctl scale-factor reads the sim's true scale factor back") {
  require_sim();
  require_fogctl();
  // Paced: the daemon steps the bench's clock (and the table with it), so every second is
  // acquired whatever the host's load, and the counts below are exact.
  LiveBench bench(50.0, json::object(), true, nullptr, {"--rate-table-port", "0"});
  REQUIRE(bench.ready_sim["rate_table_config"].is_object());
  const json truth = bench.ready_sim["scale_factor_truth"];
  REQUIRE(truth.is_object());
  std::ofstream(bench.dir / "profiles" / "spin.profile") << kSpin;
  LineClient c(bench.socket());
  REQUIRE(c.ok());
  // A subscriber sees each second's commanded rate in the live `sample` messages.
  LineClient sub(bench.socket());
  REQUIRE(sub.ok());
  REQUIRE(code_of(sub.call({{"cmd", "subscribe"}})) == "ok");
  const auto run = bench.start_run(c, "spin", {"SIM-0001"});
  json done = bench.wait_state(c, run, {"completed", "aborted", "failed"}, 120s);
  INFO("fogbenchd log in " << (bench.dir / "fogbenchd.log"));
  REQUIRE(done.contains("result"));
  REQUIRE(done["result"]["run"]["state"] == "completed");

  // Second by second, the stored rate is the schedule's: the hold is the step whose samples
  // carry the first non-zero rate, its first sample the sequence's start.
  const json samples = all_samples(c, run);
  REQUIRE(samples.size() >= 120);
  std::optional<int> hold_step;
  for (const auto& s : samples) {
    REQUIRE(s.contains("rate_in_dps"));
    if (!hold_step && s["rate_in_dps"] != 0.0) hold_step = s["step"].get<int>();
  }
  REQUIRE(hold_step);
  std::optional<double> hold_t0;
  int in_hold = 0, plus = 0, minus = 0;
  for (const auto& s : samples) {
    const double t = s["t_s"].get<double>();
    const double rate = s["rate_in_dps"].get<double>();
    INFO("t_s " << t << " step " << s["step"]);
    if (s["step"] != *hold_step) {
      CHECK(rate == 0.0);
      continue;
    }
    if (!hold_t0) hold_t0 = t;
    CHECK(rate == schedule_dps(t - *hold_t0));
    ++in_hold;
    plus += rate > 0;
    minus += rate < 0;
    // The gyro turned with the table: its output mid-step is the rate (deg/h) within 1 %.
    const double into = std::fmod(t - *hold_t0, kStepS);
    if (rate != 0.0 && into > 10 && into < kStepS - 5 && s["gyro_dph"].is_number())
      CHECK(std::abs(s["gyro_dph"].get<double>() / 3600.0 - rate) < 0.01 * std::abs(rate));
  }
  CHECK(in_hold >= 118);
  CHECK(plus == 40);
  CHECK(minus == 40);
  int pushed = 0, pushed_turning = 0;
  while (auto l = sub.line(2s)) {
    const json m = json::parse(*l, nullptr, false);
    if (!m.is_object() || m.value("type", "") != "sample") continue;
    ++pushed;
    REQUIRE(m.contains("rate_in_dps"));
    pushed_turning += m["rate_in_dps"] != 0.0;
  }
  CHECK(pushed >= 118);
  CHECK(pushed_turning == 80);

  // The export feeds fogctl scale-factor; its plateau's scale factor is the sim's truth at the
  // plateau's coil temperature (15 ppm/degC about 20 degC), within 20 ppm.
  auto exp = fogctl(bench, "run export --socket '" + bench.socket().string() + "' " + std::to_string(run) + " -o run.csv");
  INFO(exp.err);
  REQUIRE(exp.code == 0);
  auto sf = fogctl(bench, "scale-factor --json --settle 10 run.csv");
  INFO(sf.err << sf.out);
  REQUIRE(sf.code == 0);
  const json fit = json::parse(sf.out);
  REQUIRE(fit["plateaus"].size() == 1);
  const json& p = fit["plateaus"][0];
  CHECK(p["plateau"] == *hold_step);
  CHECK(p["bias_from_zero_rate"] == true);
  const double coil_c = p["coil_c"].get<double>();
  const double want = truth["sf0"].get<double>() *
                      (1.0 + 1e-6 * truth["tc_ppm_per_c"].get<double>() * (coil_c - truth["t0_c"].get<double>()));
  const double got = p["scale_factor"].get<double>();
  INFO("scale factor " << got << ", truth " << want << " at " << coil_c << " degC");
  CHECK(std::abs(got / want - 1.0) * 1e6 < 20.0);
}

TEST_CASE("e2e rate table: a fault the table reports aborts the run naming the table, the chamber safe, the samples kept") {
  require_sim();
  require_fogctl();
  LiveBench bench(50.0, {{"safe_setpoint_c", 15}}, false, nullptr, {"--rate-table-port", "0"});
  std::ofstream(bench.dir / "profiles" / "long-spin.profile") << kLongSpin;
  LineClient c(bench.socket());
  REQUIRE(c.ok());
  const auto run = bench.start_run(c, "long-spin", {"SIM-0001"});
  const std::size_t before = wait_turning(bench, c, run);

  REQUIRE(bench.sim_command({{"cmd", "fault"}, {"name", "table_fault"}, {"text", "OVERSPEED TRIP"}, {"on", true}})["ok"] == true);
  json done = bench.wait_state(c, run, {"completed", "aborted", "failed"}, 60s);
  INFO("fogbenchd log in " << (bench.dir / "fogbenchd.log"));
  REQUIRE(done.contains("result"));
  CHECK(done["result"]["run"]["state"] == "aborted");
  CHECK_THAT(done["result"]["run"]["reason"].get<std::string>(), Catch::Contains("rate table fault: OVERSPEED TRIP"));

  // The chamber at the safe setpoint, the table at rest (it braked on its fault).
  auto s = bench.wait_status(c, [](const json& r) { return r["chamber"]["setpoint_c"] == 15.0; }, 30s);
  CHECK(s["result"]["chamber"]["setpoint_c"] == 15.0);
  CHECK(table_comes_to_rest(bench, 30s));

  // What was stored is kept: every sample before the fault, the turning ones with their rate,
  // and the run exports.
  const json samples = all_samples(c, run);
  CHECK(samples.size() >= before);
  int turning = 0;
  for (const auto& smp : samples) turning += smp["rate_in_dps"] == 10.0;
  CHECK(turning >= 5);
  auto exp = fogctl(bench, "run export --socket '" + bench.socket().string() + "' " + std::to_string(run) + " -o run.csv");
  INFO(exp.err);
  CHECK(exp.code == 0);
  CHECK(slurp(bench.dir / "run.csv").find(",plateau,rate_in_dps,rate_out_dps") != std::string::npos);
}

TEST_CASE("e2e rate table: the table's link lost aborts the run naming the link, and the table is brought to rest") {
  require_sim();
  LiveBench bench(50.0, {{"safe_setpoint_c", 15}}, false, nullptr, {"--rate-table-port", "0"});
  std::ofstream(bench.dir / "profiles" / "long-spin.profile") << kLongSpin;
  LineClient c(bench.socket());
  REQUIRE(c.ok());
  const auto run = bench.start_run(c, "long-spin", {"SIM-0001"});
  const std::size_t before = wait_turning(bench, c, run);

  // The sim closes the table's connections; the table keeps turning.
  REQUIRE(bench.sim_command({{"cmd", "fault"}, {"name", "drop_table"}})["ok"] == true);
  json done = bench.wait_state(c, run, {"completed", "aborted", "failed"}, 60s);
  INFO("fogbenchd log in " << (bench.dir / "fogbenchd.log"));
  REQUIRE(done.contains("result"));
  CHECK(done["result"]["run"]["state"] == "aborted");
  CHECK_THAT(done["result"]["run"]["reason"].get<std::string>(), Catch::Contains("rate table link lost"));

  auto s = bench.wait_status(c, [](const json& r) { return r["chamber"]["setpoint_c"] == 15.0; }, 30s);
  CHECK(s["result"]["chamber"]["setpoint_c"] == 15.0);
  // The daemon reconnects and stops the table (0 deg/s commanded after the abort).
  CHECK(table_comes_to_rest(bench, 30s));
  CHECK(all_samples(c, run).size() >= before);
}
