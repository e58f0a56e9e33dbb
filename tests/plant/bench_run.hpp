// A real completed run in a real SQLite store, for the plant's tests: two units simulated over
// the shipped exp1 profile (sim::simulate), recorded sample by sample, fitted with the paper's
// model (model::fit) and verified on the same run (model::verify), as fogbenchd stores them.
#pragma once

#include <catch2/catch.hpp>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "fogbench/model/json.hpp"
#include "fogbench/model/model.hpp"
#include "fogbench/model/terms.hpp"
#include "fogbench/profiles/profile.hpp"
#include "fogbench/sim/sim.hpp"
#include "fogbench/storage/identity.hpp"
#include "fogbench/storage/models.hpp"
#include "fogbench/storage/runs.hpp"
#include "fogbench/storage/samples.hpp"
#include "fogbench/storage/store.hpp"
#include "fogbench/storage/verdict.hpp"

namespace fogbench::test {

inline std::vector<sim::SetpointSample> exp1_program() {
  std::ifstream f(std::string(FOGBENCH_SOURCE_DIR) + "/profiles/exp1.profile");
  std::stringstream ss;
  ss << f.rdbuf();
  auto p = profiles::parse_profile(ss.str(), "exp1");
  REQUIRE(p);
  std::vector<sim::SetpointSample> out;
  for (const auto& pt : profiles::nominal_setpoints(*p, 1.0)) {
    if (pt.phase == profiles::Phase::settle) continue;
    const model::Phase ph = pt.phase == profiles::Phase::heating   ? model::Phase::heating
                            : pt.phase == profiles::Phase::cooling ? model::Phase::cooling
                                                                   : model::Phase::hold;
    out.push_back({pt.setpoint_c, ph, static_cast<int>(pt.step_index)});
  }
  return out;
}

// Records one completed run of two units (lots as given) with `repeat` copies of the profile's
// samples per unit (time shifted), fits and verifies each unit. Every seventh sample carries a
// compensated rate (gyro_dph - 0.5 deg/h), the others none. The run carries `identity` when
// given (a run of a bench before issue 13 has none). Returns the run id.
inline std::int64_t record_run(storage::Store& store, const std::vector<std::optional<std::string>>& lots,
                               int repeat = 1, std::uint64_t seed = 5, bool analyse = true,
                               const std::optional<storage::RunIdentity>& identity = std::nullopt) {
  sim::SimConfig cfg;
  cfg.seed = seed;
  cfg.units = {sim::UnitParams{}, sim::UnitParams{}};
  cfg.units[0].serial = "FOG-0001";
  cfg.units[1].serial = "FOG-0002";
  auto runs = sim::simulate(cfg, exp1_program());
  REQUIRE(runs);
  storage::NewRun nr;
  nr.profile_name = "exp1";
  nr.unit_serials = {"FOG-0001", "FOG-0002"};
  nr.unit_lots = lots;
  nr.identity = identity;
  auto id = store.create_run(nr);
  REQUIRE(id);
  REQUIRE(store.set_run_state(*id, storage::RunState::running, "started"));
  const double span = (*runs)[0].time_s.back() + 1;
  for (int k = 0; k < repeat; ++k) {
    std::vector<storage::SampleRow> rows;
    for (int u = 0; u < 2; ++u) {
      const model::RunData& d = (*runs)[static_cast<std::size_t>(u)];
      for (std::size_t i = 0; i < d.size(); ++i) {
        storage::SampleRow r;
        r.unit_index = u;
        r.t_s = d.time_s[i] + k * span;
        r.wall_time = 1.7e9 + r.t_s;
        r.setpoint_c = d.setpoint_c.empty() ? storage::kNoValue : d.setpoint_c[i];
        r.chamber_c = d.chamber_c.empty() ? storage::kNoValue : d.chamber_c[i];
        r.gyro_dph = d.gyro_dph[i];
        r.frames = 100;
        r.t1_c = d.t1_c[i];
        r.t2_c = d.t2_c[i];
        r.phase = d.phase.empty() ? model::Phase::hold : d.phase[i];
        r.step = d.step.empty() ? 0 : d.step[i];
        r.flags = static_cast<std::uint8_t>(i % 97 == 0 ? 1 : 0);
        r.since_power_on_s = i % 2 ? storage::kNoValue : r.t_s + 60;
        r.compensated_dph = i % 7 ? storage::kNoValue : r.gyro_dph - 0.5;
        rows.push_back(r);
      }
    }
    REQUIRE(store.append_samples(*id, rows));
  }
  REQUIRE(store.add_event(*id, storage::EventKind::note, R"({"text":"a tab\there, a quote ' and \" and a \\ backslash"})", 12.5));
  REQUIRE(store.set_run_state(*id, storage::RunState::completed, "profile finished"));
  if (!analyse) return *id;
  for (int u = 0; u < 2; ++u) {
    const model::RunData& d = (*runs)[static_cast<std::size_t>(u)];
    auto m = model::fit(d, *model::parse_terms("paper"), model::FitOptions{});
    REQUIRE(m);
    storage::NewModel nm;
    nm.serial = cfg.units[static_cast<std::size_t>(u)].serial;
    nm.run_id = *id;
    nm.model_json = model::to_json(*m).dump();
    nm.method = "paper";
    nm.terms = m->terms_string();
    auto ref = store.put_model(nm);
    REQUIRE(ref);
    auto v = model::verify(*m, d, 0.2);
    REQUIRE(v);
    storage::NewVerification nv;
    nv.run_id = *id;
    nv.unit_index = u;
    nv.model_id = ref->id;
    nv.result_json = model::to_json(*v).dump();
    nv.pass = v->pass;
    REQUIRE(store.put_verification(nv));
    // The verdict, as the daemon decides it for a bare verify run (the analysis settings).
    storage::NewVerdict verdict;
    verdict.serial = nm.serial;
    verdict.run_id = *id;
    verdict.unit_index = u;
    verdict.model_id = ref->id;
    verdict.verdict = v->pass ? "pass" : "fail";
    verdict.rule = "analysis";
    REQUIRE(store.put_verdict(verdict));
  }
  return *id;
}

inline std::filesystem::path temp_store_path(const std::string& name) {
  auto p = std::filesystem::temp_directory_path() / ("fogbench-plant-" + std::to_string(::getpid()) + "-" + name + ".db");
  std::filesystem::remove(p);
  std::filesystem::remove(p.string() + "-wal");
  std::filesystem::remove(p.string() + "-shm");
  return p;
}

}  // namespace fogbench::test
