// Benchmark: what online compensation (daemon/live_compensation.hpp) adds to the acquisition
// path. The station's whole tick (readings -> rows with quality flags -> live compensation ->
// SQLite insert -> `sample` messages) of 2 units over a 30-min profile, on an in-memory store,
// once with each unit's model stored (compensated live) and once without (compensation off:
// no model, nothing computed), interleaved; thread CPU time per unit-second. Also the live step
// alone (LiveCompensation::step on stored rows). Target (issue 13): under 1 us per unit-second.
// The model: the paper's two terms plus a filter and a product (two 61-sample slopes), as
// bench_firmware. Usage: bench_live_compensation [repeats=7]
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <fstream>
#include <sstream>
#include <vector>

#include "fogbench/daemon/live_compensation.hpp"
#include "fogbench/daemon/station.hpp"
#include "fogbench/model/json.hpp"
#include "fogbench/storage/models.hpp"
#include "fogbench/storage/store.hpp"

#include <spdlog/spdlog.h>

using namespace fogbench;

namespace {

double cpu_s() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + static_cast<double>(ts.tv_nsec) * 1e-9;
}

[[noreturn]] void fail(const std::string& why) {
  std::fprintf(stderr, "bench_live_compensation: %s\n", why.c_str());
  std::exit(1);
}

daemon::DaemonConfig config() {
  const std::filesystem::path dir = std::filesystem::path(FOGBENCH_SOURCE_DIR) / "tests" / "golden";
  std::ifstream in(dir / "config.json");
  std::stringstream ss;
  ss << in.rdbuf();
  auto c = daemon::parse_daemon_config(nlohmann::json::parse(ss.str()), dir);
  if (!c) fail("tests/golden/config.json: " + c.error());
  return *c;
}

std::string model_json() {
  model::Model m;
  m.mu0_dph = -8.0;
  for (const char* text : {"d(T1)@40", "grad@40", "lp(T1,600)", "T1*d(T1)@35"}) {
    auto t = model::parse_term(text);
    if (!t) fail(std::string("term ") + text);
    model::FittedTerm f;
    f.term = *t;
    f.coef = 0.5;
    m.terms.push_back(f);
  }
  return model::to_json(m).dump();
}

// One run of the `short` profile (1801 s) on 2 units; thread CPU seconds spent in tick().
double run_once(const daemon::DaemonConfig& cfg, bool with_model, std::size_t& unit_seconds, std::size_t& compensated) {
  auto store = storage::Store::open(":memory:");
  if (!store) fail("store: " + store.error().message);
  if (with_model)
    for (const char* serial : {"FOG-0001", "FOG-0002"}) {
      storage::NewModel nm;
      nm.serial = serial;
      nm.model_json = model_json();
      if (!store->put_model(nm)) fail("put_model");
    }
  daemon::Station st(cfg, *store, 1.0, [] { return std::string("2026-01-01T00:00:00Z"); });
  std::size_t published = 0;
  st.set_publisher([&](const nlohmann::json& m) {
    if (m["type"] == "sample" && m["compensated_dph"].is_number()) ++compensated;
    ++published;
  });
  if (!st.start_run("short", {"FOG-0001", "FOG-0002"}, storage::Purpose::fit, {{"cmd", "run.start"}})) fail("run.start");
  // A chamber that follows its setpoint, coils that lag it: enough to move the model's inputs.
  double air = 20.0, sp = 20.0, t1[2] = {20, 20}, t2[2] = {20, 20};
  double cpu = 0.0;
  // 1700 of the profile's 1801 s: the run does not end, so its fit (not acquisition) is left out.
  for (int k = 0; st.active_run_id() && k < 1700; ++k) {
    air += std::clamp(sp - air, -5.0 / 60, 5.0 / 60);
    daemon::TickInput in;
    in.wall_time = 1.7e9 + k;
    in.chamber_c = air;
    in.chamber_setpoint_c = sp;
    for (int u = 0; u < 2; ++u) {
      t2[u] += (air - t2[u]) / 60.0;
      t1[u] += (0.5 * (t2[u] + air) - t1[u]) / 240.0;
      daemon::UnitReading r;
      r.gyro_dph = -8.0 + 0.01 * std::sin(k * 0.1 + u);
      r.frames = 100;
      r.t1_c = t1[u];
      r.t2_c = t2[u];
      in.units.push_back(r);
    }
    const double t0 = cpu_s();
    sp = st.tick(k, in).setpoint_c;
    cpu += cpu_s() - t0;
    unit_seconds += 2;
  }
  return cpu;
}

}  // namespace

int main(int argc, char** argv) {
  const int repeats = argc > 1 ? std::atoi(argv[1]) : 7;
  spdlog::set_level(spdlog::level::warn);  // "no live compensation (no model)" for every run off
  const auto cfg = config();
  std::vector<double> off_ns, on_ns;
  std::size_t compensated = 0;
  for (int rep = 0; rep < repeats; ++rep) {
    for (bool with : {false, true}) {
      std::size_t us = 0, comp = 0;
      const double cpu = run_once(cfg, with, us, comp);
      (with ? on_ns : off_ns).push_back(cpu / static_cast<double>(us) * 1e9);
      if (with) compensated = comp;
      else if (comp != 0) fail("compensated without a model");
    }
  }
  if (compensated == 0) fail("nothing compensated with the model");
  std::sort(off_ns.begin(), off_ns.end());
  std::sort(on_ns.begin(), on_ns.end());
  const double off = off_ns[off_ns.size() / 2], on = on_ns[on_ns.size() / 2];

  // The live step alone, over rows as the station stores them.
  auto store = storage::Store::open(":memory:");
  storage::NewModel nm;
  nm.serial = "FOG-0001";
  nm.model_json = model_json();
  if (!store || !store->put_model(nm)) fail("store");
  constexpr int n = 1'000'000;
  std::vector<double> step_ns;
  double sink = 0.0;
  for (int rep = 0; rep < 5; ++rep) {
    auto live = daemon::LiveCompensation::load(*store, {"FOG-0001"});
    storage::SampleRow r;
    const double t0 = cpu_s();
    for (int i = 0; i < n; ++i) {
      r.t1_c = 20.0 + 10.0 * std::sin(i * 1e-3);
      r.t2_c = r.t1_c - 0.3;
      r.chamber_c = r.t1_c;
      r.gyro_dph = -8.0;
      const double v = live.step(0, r);
      if (std::isfinite(v)) sink += v;
    }
    step_ns.push_back((cpu_s() - t0) / n * 1e9);
  }
  std::sort(step_ns.begin(), step_ns.end());
  std::printf("station tick, 2 units, short profile (%zu unit-seconds compensated per run), thread CPU per unit-second, median of %d:\n",
              compensated, repeats);
  std::printf("  without live compensation %.0f ns, with %.0f ns: +%.0f ns (ratio %.3f); target +1000 ns\n", off, on, on - off,
              on / off);
  std::printf("  LiveCompensation::step alone: %.0f ns per unit-second (median of 5 x %d) [%g]\n", step_ns[2], n,
              sink != 0.0 ? 1.0 : 0.0);
  return 0;
}
