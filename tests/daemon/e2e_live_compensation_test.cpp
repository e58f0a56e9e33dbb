// Online compensation on the live mock bench: fogbenchd fits exp1, then compensates an exp2 run
// of the same serials live with that model. The stored series (run.samples), the published one
// (`compensated_dph` of each `sample` message) and fogctl's CSV export all equal model::firmware's
// Compensator run offline over the stored inputs, to 1e-9 deg/h, for every sample.
#include "live_bench.hpp"

#include <cmath>
#include <map>
#include <sys/wait.h>

#include "fogbench/model/firmware.hpp"
#include "fogbench/model/json.hpp"
#include "fogbench/model/stats.hpp"
#include "fogbench/storage/csv.hpp"

using namespace fogbench;
using namespace fogbench::daemon::test;
using namespace fogbench::daemon::test::live;
using nlohmann::json;
using namespace std::chrono_literals;

namespace {

double num(const json& v) { return v.is_number() ? v.get<double>() : NAN; }

std::vector<json> all_samples(LineClient& c, std::int64_t run, int unit) {
  std::vector<json> out;
  for (std::int64_t offset = 0;;) {
    auto r = c.call({{"cmd", "run.samples"}, {"run_id", run}, {"unit", unit}, {"offset", offset}, {"limit", 10000}});
    REQUIRE(code_of(r) == "ok");
    const auto& rows = r["result"]["samples"];
    for (const auto& s : rows) out.push_back(s);
    offset += static_cast<std::int64_t>(rows.size());
    if (rows.size() < 10000) break;
  }
  return out;
}

}  // namespace

TEST_CASE("e2e live compensation: a run compensated live with the serial's model equals the firmware program run offline on its stored inputs") {
  require_sim();
  require_fogctl();
  // Paced: the daemon steps the mock bench's world second by second, so a loaded machine makes
  // the run slower, never one with seconds not read.
  LiveBench bench(100.0, json::object(), true);
  INFO("test dir " << bench.dir);
  LineClient c(bench.socket());
  REQUIRE(c.ok());
  REQUIRE(json::parse(*c.line(10s))["type"] == "hello");

  const auto fit = bench.start_run(c, "exp1", {"SIM-0001", "SIM-0002"});
  json done = bench.wait_state(c, fit, {"completed", "aborted", "failed", "interrupted"}, 270s);
  INFO(done["result"]["run"].dump());
  REQUIRE(done["result"]["run"]["state"] == "completed");
  REQUIRE(done["result"]["models"].size() == 2);
  // No model when the fit run started: its series is all null.
  for (const auto& s : all_samples(c, fit, 0)) REQUIRE(s["compensated_dph"].is_null());

  // A subscriber follows the second run from its start.
  LineClient sub(bench.socket());
  REQUIRE(sub.ok());
  REQUIRE(json::parse(*sub.line(10s))["type"] == "hello");
  REQUIRE(code_of(sub.call({{"cmd", "subscribe"}})) == "ok");
  const auto run = bench.start_run(c, "exp2", {"SIM-0001", "SIM-0002"}, "verify");
  std::map<int, std::vector<json>> pushed;  // by unit
  const auto deadline = SteadyClock::now() + 270s;
  bool ended = false;
  while (!ended && SteadyClock::now() < deadline) {
    auto l = sub.line(30s);
    if (!l) continue;
    auto m = json::parse(*l, nullptr, false);
    if (!m.is_object() || m.value("run_id", json()) != run) continue;
    if (m["type"] == "sample") pushed[m["unit"].get<int>()].push_back(m);
    if (m["type"] == "event" && m["kind"] == "state" && m["detail"]["to"] != "running" && m["detail"]["to"] != "settling")
      ended = true;
  }
  REQUIRE(ended);
  done = bench.wait_state(c, run, {"completed", "aborted", "failed", "interrupted"}, 270s);
  INFO(done["result"]["run"].dump());
  REQUIRE(done["result"]["run"]["state"] == "completed");

  for (int unit : {0, 1}) {
    const std::string serial = unit == 0 ? "SIM-0001" : "SIM-0002";
    INFO(serial);
    auto m = c.call({{"cmd", "model.get"}, {"serial", serial}});
    REQUIRE(code_of(m) == "ok");
    auto model = model::model_from_json(m["result"]["model"]);
    REQUIRE(model.has_value());
    auto program = model::firmware::compile(*model);
    REQUIRE(program.has_value());
    const int warm = model::firmware::warm_up_samples(*program);

    // Offline, from the stored inputs and the documented rule: a fresh compensator from the
    // first sample and after any sample missing T1 or T2 or flagged out_of_range; the first
    // `warm` samples of each stretch null.
    const auto stored = all_samples(c, run, unit);
    REQUIRE(stored.size() > 3000);
    std::optional<model::firmware::Compensator> comp;
    int k = 0;
    std::size_t values = 0, gaps = 0;
    for (const auto& s : stored) {
      INFO("t_s " << s["t_s"]);
      const double t1 = num(s["t1_c"]), t2 = num(s["t2_c"]);
      double expect = NAN;
      if (!std::isfinite(t1) || !std::isfinite(t2) || (s["flags"].get<int>() & model::flag::out_of_range)) {
        comp.reset();
        k = 0;
        ++gaps;
      } else {
        if (!comp) comp.emplace(*program);
        const double mu = comp->step({t1, t2, num(s["chamber_c"]), num(s["since_power_on_s"])});
        if (k++ >= warm && std::isfinite(num(s["gyro_dph"]))) expect = num(s["gyro_dph"]) - mu;
      }
      const double live = num(s["compensated_dph"]);
      REQUIRE(std::isfinite(live) == std::isfinite(expect));
      if (std::isfinite(expect)) {
        REQUIRE(std::abs(live - expect) <= 1e-9);
        ++values;
      }
    }
    INFO(values << " of " << stored.size() << " compensated, " << gaps << " gap seconds, warm-up " << warm);
    CHECK(values > stored.size() / 2);
    CHECK(values > 3000);
    // What it removes is the drift: over the compensated seconds, ramps included, the live
    // compensated rate varies far less than the raw one.
    std::vector<double> raw, comp_dph;
    for (const auto& x : stored)
      if (x["compensated_dph"].is_number()) {
        raw.push_back(num(x["gyro_dph"]));
        comp_dph.push_back(num(x["compensated_dph"]));
      }
    CHECK(model::stddev(comp_dph) < 0.5 * model::stddev(raw));

    // Published as stored, second by second.
    const auto& p = pushed[unit];
    REQUIRE(p.size() == stored.size());
    for (std::size_t i = 0; i < p.size(); ++i) {
      REQUIRE(p[i]["t_s"] == stored[i]["t_s"]);
      REQUIRE(p[i].contains("compensated_dph"));
      REQUIRE(p[i]["compensated_dph"] == stored[i]["compensated_dph"]);
    }

    // fogctl's CSV export carries the column; the importer reads it back.
    const auto csv = bench.dir / ("export-" + std::to_string(unit) + ".csv");
    const std::string cmd = "'" + (kBin / "fogctl").string() + "' run export " + std::to_string(run) + " --unit " +
                            std::to_string(unit) + " --include-settle --socket '" + bench.socket().string() + "' -o '" +
                            csv.string() + "' 2>/dev/null";
    REQUIRE(WEXITSTATUS(std::system(cmd.c_str())) == 0);
    auto back = storage::read_csv_file(csv, {});
    REQUIRE(back.has_value());
    REQUIRE(back->compensated_dph.size() == stored.size());
    for (std::size_t i = 0; i < stored.size(); ++i) {
      const double live = num(stored[i]["compensated_dph"]);
      REQUIRE(std::isfinite(back->compensated_dph[i]) == std::isfinite(live));
      if (std::isfinite(live)) REQUIRE(back->compensated_dph[i] == live);
    }
  }
}
