// The run state machine: start, resume, abort, the tick (profile, chamber faults, the second's
// samples) and the end of a run. The station's other rooms are listed in station.hpp.
//
// Why this file is longer than 800 lines: its one job is one run's state machine. start,
// resume, the tick and the end share the Run record and its transitions (every state change
// and event goes through transition() and event()); the parts that stand alone (profiles,
// analysis, status, the plant link, the sample rows) are already their own files.
#include "fogbench/daemon/station.hpp"

#include "fogbench/daemon/sample_rows.hpp"
#include "fogbench/storage/models.hpp"
#include "fogbench/storage/run_data.hpp"
#include "fogbench/storage/store.hpp"

#include <algorithm>
#include <cassert>
#include <chrono>
#include <cmath>
#include <ctime>
#include <fstream>
#include <regex>
#include <sstream>
#include <stdexcept>

#include <spdlog/spdlog.h>

#include "fogbench/model/json.hpp"
#include "fogbench/model/model.hpp"
#include "fogbench/model/terms.hpp"
#include "fogbench/model/workbench.hpp"

namespace fogbench::daemon {

using nlohmann::json;
using storage::RunState;

std::string iso8601_now() { return storage::iso8601_utc(std::chrono::system_clock::now()); }

namespace {

// A setpoint that moved at least this much should have moved the PV (several register steps
// of 0.1 degC): below it a frozen PV cannot be told from a chamber at rest.
constexpr double kSetpointMovedC = 0.5;

}  // namespace

const signing::SigningKey& Station::signing_key() {
  if (!signing_key_) {
    auto k = signing::SigningKey::generate();
    if (!k) throw std::runtime_error("signing key: " + k.error());
    signing_key_ = std::move(*k);
  }
  return *signing_key_;
}

Station::Station(DaemonConfig config, storage::Store& store, double time_scale, WallClock wall_clock)
    : config_(std::move(config)),
      store_(store),
      time_scale_(time_scale),
      wall_clock_(wall_clock ? std::move(wall_clock) : WallClock(iso8601_now)),
      setpoint_c_(config_.safe_setpoint_c),
      power_(config_.drivers.units.size()) {}

ApiResult<std::vector<std::int64_t>> Station::recover() {
  recovery_tried_clock_s_ = clock_s_;
  // The first try at start-up waits for a lock like any write; the retries do not.
  auto ids = journal_.without_waiting_if_refused(
      [&] { return store_.mark_interrupted_runs("daemon restarted: the run was in progress when it stopped"); });
  journal_.set_refused(!ids && WriteJournal::may_pass(ids.error().code));
  if (!ids) {
    recovery_error_ = std::string(storage::to_string(ids.error().code)) + ": " + ids.error().message;
    return std::unexpected(from_store(ids.error()));
  }
  recovery_error_.reset();
  return *ids;
}

namespace {
ApiError not_recovered(const std::string& why) {
  return {ErrorCode::internal,
          "the runs a crash left in progress are not yet marked interrupted (" + why +
              "); fogbenchd retries every 10 s and starts no run until it has"};
}
}  // namespace

std::optional<std::int64_t> Station::active_run_id() const {
  if (!run_) return std::nullopt;
  return run_->id;
}

void Station::write_or_keep(WriteJournal::Write w) {
  if (journal_.write_or_keep(std::move(w))) unrecorded_tried_clock_s_ = clock_s_;
}

void Station::event(std::int64_t run_id, storage::EventKind kind, const json& detail,
                    std::optional<double> t_s) {
  // An event that cannot be stored is still published and logged, and kept to be written
  // when the store takes it again; the daemon keeps running.
  write_or_keep({run_id, std::nullopt, "", kind, detail.dump(), t_s});
  emit(protocol::to_json(protocol::EventMessage{run_id, t_s, std::string(storage::to_string(kind)), detail}));
}

void Station::audit(std::int64_t run_id, const json& command) {
  std::optional<double> t_s;
  if (run_ && run_->id == run_id) t_s = run_->elapsed_s;
  event(run_id, storage::EventKind::command, command, t_s);
}

namespace {
constexpr const char* kGyroAxisNames[] = {"x", "y", "z"};  // axis 0, 1, 2 as events and messages name them
}  // namespace

void Station::note_silent_axes(ActiveRun& run, std::size_t unit, const UnitReading& u, const TickInput& in,
                               double t_s) {
  const std::size_t ci = run.config_index[unit];
  const drivers::GyroChannelConfig& gyro = config_.drivers.units[ci].gyro;
  const int axes = unit < run.unit_axes.size() ? run.unit_axes[unit] : 1;  // the run's, not the config's
  if (axes < 2 || !in.gyro_read || !in.gyro_link_up || u.extra_axes.empty()) return;
  std::array<std::uint32_t, 3> sent{u.frames + u.frames_corrupt, 0, 0};
  for (std::size_t k = 0; k < u.extra_axes.size() && k + 1 < sent.size(); ++k)
    sent[k + 1] = u.extra_axes[k].frames + u.extra_axes[k].frames_corrupt;
  if (std::ranges::all_of(sent, [](std::uint32_t n) { return n == 0; })) return;  // the unit is silent, not an axis
  if (run.axis_silence_noted.size() < run.config_index.size()) run.axis_silence_noted.resize(run.config_index.size());
  for (std::size_t k = 0; k < sent.size() && k < static_cast<std::size_t>(axes); ++k) {
    if (sent[k] != 0 || run.axis_silence_noted[unit][k]) continue;
    run.axis_silence_noted[unit][k] = true;
    const auto id = gyro.axis_id(static_cast<std::uint8_t>(k));
    spdlog::warn("run {}: unit {} ({}) axis {} (CAN id {}) sent no frame at t_s {} s while its other axes did", run.id, unit,
                 run.serials[unit], kGyroAxisNames[k], id, t_s);
    event(run.id, storage::EventKind::fault,
          {{"gyro_axis", "silent"}, {"unit", static_cast<int>(unit)}, {"serial", run.serials[unit]}, {"axis", kGyroAxisNames[k]},
           {"can_id", id}, {"t_s", t_s},
           {"reason", "no frame on CAN id " + std::to_string(id) + " for a second while the unit's other axes sent "
                      "(its seconds are flagged missing; said once per axis and run)"}},
          t_s);
  }
}

void Station::note_saturated_axes(ActiveRun& run, std::size_t unit, const UnitReading& u, double t_s) {
  std::array<std::uint32_t, 3> at_limit{u.frames_saturated, 0, 0};
  std::array<std::uint32_t, 3> frames{u.frames, 0, 0};
  for (std::size_t k = 0; k < u.extra_axes.size() && k + 1 < at_limit.size(); ++k) {
    at_limit[k + 1] = u.extra_axes[k].frames_saturated;
    frames[k + 1] = u.extra_axes[k].frames;
  }
  if (run.axis_saturation_noted.size() < run.config_index.size()) run.axis_saturation_noted.resize(run.config_index.size());
  const drivers::GyroChannelConfig& gyro = config_.drivers.units[run.config_index[unit]].gyro;
  // The largest |rate| the int32 counts hold at the unit's scale (in increment mode, at its
  // nominal frame rate), deg/s.
  const double holds_dps = std::abs(gyro.mean_counts_to_rate_dph(2147483647.0)) / 3600.0;
  for (std::size_t k = 0; k < at_limit.size(); ++k) {
    if (at_limit[k] == 0 || run.axis_saturation_noted[unit][k]) continue;
    run.axis_saturation_noted[unit][k] = true;
    const auto id = gyro.axis_id(static_cast<std::uint8_t>(k));
    std::ostringstream why;
    why << at_limit[k] << " of " << frames[k] << " frames on CAN id " << id
        << " at the int32 count limit: the rate is beyond what the unit's scale carries (about +-" << holds_dps
        << " deg/s), so the reading is clipped (its seconds are flagged out_of_range; said once per axis and run)";
    spdlog::warn("run {}: unit {} ({}) axis {} saturated at t_s {} s: {}", run.id, unit, run.serials[unit], kGyroAxisNames[k], t_s,
                 why.str());
    event(run.id, storage::EventKind::fault,
          {{"gyro_axis", "saturated"}, {"unit", static_cast<int>(unit)}, {"serial", run.serials[unit]}, {"axis", kGyroAxisNames[k]},
           {"can_id", id}, {"t_s", t_s}, {"holds_dps", holds_dps}, {"reason", why.str()}},
          t_s);
  }
}

void Station::transition(ActiveRun& run, RunState to, const std::string& reason,
                         std::optional<double> t_s) {
  const RunState from = run.state;
  run.state = to;
  write_or_keep({run.id, to, reason, storage::EventKind::state, "", t_s});
  emit(protocol::to_json(protocol::EventMessage{
      run.id, t_s, "state",
      {{"from", std::string(storage::to_string(from))}, {"to", std::string(storage::to_string(to))}, {"reason", reason}}}));
}

// A run started while the chamber cannot be polled would only wait out link_loss.tolerance_s
// and abort: refused at once instead. Before the first poll nothing is known and nothing refused.
std::optional<ApiError> Station::chamber_unavailable() const {
  if (!last_input_ || !last_input_->chamber_link_down) return std::nullopt;
  return ApiError{ErrorCode::unavailable,
                  "the chamber link is down (the chamber cannot be polled): no run starts until it answers again"};
}

ApiResult<std::int64_t> Station::start_run(const std::string& profile_name,
                                           const std::vector<std::string>& serials,
                                           storage::Purpose purpose, const json& command,
                                           const OperatorId& op) {
  std::vector<SlotUnit> units;
  for (std::size_t i = 0; i < serials.size(); ++i) {
    for (std::size_t j = 0; j < i; ++j)
      if (serials[j] == serials[i]) return api_error(ErrorCode::bad_request, "units: " + serials[i] + " given twice");
    const auto ci = find_slot(config_.drivers.units, serials[i]);
    if (!ci) return api_error(ErrorCode::unknown_serial, "unit " + serials[i] + ": not configured on this bench");
    units.push_back({*ci, serials[i]});
  }
  return start_run_in_slots(profile_name, units, purpose, command, op);
}

ApiResult<std::int64_t> Station::start_run_in_slots(const std::string& profile_name, const std::vector<SlotUnit>& units,
                                           storage::Purpose purpose, const json& command,
                                           const OperatorId& op) {
  if (auto busy = station_busy()) return std::unexpected(*busy);
  if (recovery_error_) return std::unexpected(not_recovered(*recovery_error_));
  if (auto down = chamber_unavailable()) return std::unexpected(*down);
  if (units.empty()) return api_error(ErrorCode::bad_request, "units: expected at least one serial");

  const std::vector<std::string> serials = serials_of(units);
  std::vector<std::size_t> index;
  std::vector<std::string> slots;
  for (std::size_t i = 0; i < serials.size(); ++i) {
    for (std::size_t j = 0; j < i; ++j) {
      if (serials[j] == serials[i]) return api_error(ErrorCode::bad_request, "units: " + serials[i] + " given twice");
      if (units[j].config_index == units[i].config_index)
        return api_error(ErrorCode::bad_request, "slots: slot " + config_.drivers.units[units[i].config_index].slot + " given twice");
    }
    assert(units[i].config_index < config_.drivers.units.size());
    index.push_back(units[i].config_index);
    slots.push_back(config_.drivers.units[units[i].config_index].slot);
    if (purpose == storage::Purpose::verify) {
      auto m = store_.current_model(serials[i]);
      if (!m) return std::unexpected(from_store(m.error()));
      if (!*m) return api_error(ErrorCode::unknown_serial, "unit " + serials[i] + ": no model to verify");
      // A three-axis unit's y and z are verified against their own models: each needs one.
      if (config_.drivers.units[units[i].config_index].gyro.axes == 3)
        for (const char* axis : {"y", "z"}) {
          auto a = store_.current_model(serials[i], axis);
          if (!a) return std::unexpected(from_store(a.error()));
          if (!*a)
            return api_error(ErrorCode::unknown_serial, "unit " + serials[i] + " axis " + axis +
                                                            ": no model to verify (a three-axis unit needs one per axis: fit a run of it first)");
        }
    }
  }

  std::string text;
  auto profile = load_profile(profile_name, &text);
  if (!profile) return std::unexpected(profile.error());

  storage::NewRun nr;
  nr.profile_name = profile_name;
  nr.profile_text = text;
  nr.purpose = purpose;
  nr.config_json = config_.source.dump();
  nr.time_scale = time_scale_;
  nr.unit_serials = serials;
  auto lots = unit_lots(command, serials);  // station_plant.cpp
  if (!lots) return std::unexpected(lots.error());
  nr.unit_lots = std::move(*lots);
  nr.unit_slots = std::move(slots);
  for (std::size_t ci : index) nr.unit_axes.push_back(config_.drivers.units[ci].gyro.axes);
  std::vector<UnitPowerOn> power;
  for (std::size_t ci : index) {
    UnitPowerOn p;
    p.since_power_on_s = power_.since_power_on_s(ci, clock_s_);
    // Its wall time: the last tick's, less the daemon seconds since (time_scale per wall second).
    if (p.since_power_on_s && last_input_ && last_input_->wall_time > 0)
      p.powered_on_wall_s = last_input_->wall_time - *p.since_power_on_s / time_scale_;
    power.push_back(p);
  }
  nr.identity = make_run_identity(config_.station_id, op, nr.config_json, text, serials, power);
  auto id = store_.create_run(nr);
  if (!id) return std::unexpected(from_store(id.error()));

  ActiveRun run;
  run.id = *id;
  run.purpose = purpose;
  run.profile_name = profile_name;
  run.serials = serials;
  run.config_index = std::move(index);
  run.slots = nr.unit_slots;
  run.executor = std::make_unique<profiles::Executor>(std::move(*profile));
  if (!run.executor->profile().rate_steps.empty()) run.rates.emplace(run.executor->profile());
  run.table_max_abs_dps = run.rates ? run.rates->max_abs_rate_dps() : 0.0;
  run.unit_axes = nr.unit_axes;
  run.live = LiveCompensation::load(store_, serials);
  run_analysis_[*id] = config_.analysis;
  run_ = std::move(run);
  event(*id, storage::EventKind::command, command, std::nullopt);
  return *id;
}

std::optional<ApiError> Station::station_busy() const {
  if (run_) return ApiError{ErrorCode::busy, "run " + std::to_string(run_->id) + " is " +
                                                 std::string(storage::to_string(run_->state))};
  if (resuming_) return ApiError{ErrorCode::busy, "run " + std::to_string(*resuming_) +
                                                      " is being resumed (its stored seconds are replayed)"};
  return std::nullopt;
}

ApiResult<std::int64_t> Station::resume_run(std::int64_t run_id, double now_wall_time, const json& command) {
  auto r = begin_resume(run_id);
  if (!r) return std::unexpected(r.error());
  if (auto ok = replay_stored(store_, *r); !ok) return std::unexpected(ok.error());
  return finish_resume(std::move(*r), now_wall_time, command);
}

void Station::resume_run_async(std::int64_t run_id, double now_wall_time, const json& command, JobOrigin origin,
                               ResumeDone done) {
  auto r = begin_resume(run_id);
  if (!r) return done(std::unexpected(r.error()));
  resuming_ = run_id;
  auto replay = std::make_shared<ResumeReplay>(std::move(*r));
  const auto submitted = std::chrono::steady_clock::now();
  // The job touches only `replay` and the worker's store; the rest is decided on the loop.
  offload_->submit([this, replay, run_id, now_wall_time, command, submitted, done](storage::Store& reader) -> Offload::Then {
    auto ok = std::make_shared<ApiResult<void>>(replay_stored(reader, *replay));
    return [this, replay, ok, run_id, now_wall_time, command, submitted, done] {
      if (resuming_ == run_id) resuming_.reset();
      if (!*ok) return done(std::unexpected(ok->error()));
      const double took_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - submitted).count();
      done(finish_resume(std::move(*replay), now_wall_time + took_s, command));
    };
  }, std::move(origin));
}

ApiResult<Station::ResumeReplay> Station::begin_resume(std::int64_t run_id) {
  if (auto busy = station_busy()) return std::unexpected(*busy);
  if (recovery_error_) return std::unexpected(not_recovered(*recovery_error_));
  if (auto down = chamber_unavailable()) return std::unexpected(*down);
  auto detail = store_.get_run(run_id);
  if (!detail) return std::unexpected(from_store(detail.error()));
  const storage::RunRecord& rec = detail->run;
  if (rec.state != RunState::interrupted)
    return api_error(ErrorCode::bad_request, "run_id: run " + std::to_string(run_id) + " is " +
                                                 std::string(storage::to_string(rec.state)) +
                                                 "; only an interrupted run resumes");
  ResumeReplay replay;
  replay.policy = config_.link_loss.policy;
  ActiveRun& run = replay.run;
  run.id = run_id;
  run.purpose = rec.purpose;
  run.profile_name = rec.profile_name;
  for (const auto& u : rec.units) {
    // In the slot it was stored in; a run stored before slots, in the slot of its default serial.
    const auto ci = find_slot(config_.drivers.units, u.serial,
                              u.slot ? std::optional<std::string_view>(*u.slot) : std::nullopt);
    if (!ci)
      return api_error(ErrorCode::unknown_serial, "unit " + u.serial + (u.slot ? " (slot " + *u.slot + ")" : "") +
                                                      ": not configured on this bench");
    run.serials.push_back(u.serial);
    run.config_index.push_back(*ci);
    run.slots.push_back(u.slot ? *u.slot : config_.drivers.units[*ci].slot);
    run.unit_axes.push_back(u.axes);  // as stored with the run
  }
  auto profile = check_profile_text(rec.profile_text, rec.profile_name + ".profile");
  if (!profile) return std::unexpected(profile.error());
  run.executor = std::make_unique<profiles::Executor>(std::move(*profile));
  if (!run.executor->profile().rate_steps.empty()) run.rates.emplace(run.executor->profile());
  run.table_max_abs_dps = run.rates ? run.rates->max_abs_rate_dps() : 0.0;
  // The live compensation with the models the run started with; its state is rebuilt from the
  // stored seconds by the replay (the gap's below restart it).
  const auto recorded = LiveCompensation::recorded_models(*detail);
  run.live = LiveCompensation::load(store_, run.serials, recorded);
  run.live_noted = !recorded.empty();
  return replay;
}

ApiResult<void> Station::replay_stored(storage::Store& store, ResumeReplay& r) {
  ActiveRun& run = r.run;
  const std::int64_t run_id = run.id;
  // Replay the stored seconds through the executor exactly as tick() fed them, gaps held. Page
  // by page (every unit's rows at the same offset), so that memory holds one page per unit
  // whatever the run's length: a 10-day run of 8 units would otherwise hold 7 million rows
  // (about 700 MB) for the length of the replay.
  constexpr int kPageRows = 10000;
  const std::size_t units = run.serials.size();
  std::vector<std::vector<storage::SampleRow>> page(units);
  std::vector<char> ended(units, 0);  // a unit whose stored rows are all read
  bool common = true;                 // every unit still has rows at this offset
  r.n = 0;
  r.last_t_s = -1.0;
  r.flagged.assign(units, 0);
  for (std::int64_t off = 0;; off += kPageRows) {
    bool any = false;
    for (std::size_t u = 0; u < units; ++u) {
      page[u].clear();
      if (ended[u]) continue;
      auto got = store.get_samples(run_id, static_cast<int>(u), off, kPageRows);
      if (!got) return std::unexpected(from_store(got.error()));
      page[u] = std::move(*got);
      if (page[u].size() < static_cast<std::size_t>(kPageRows)) ended[u] = 1;
      any = any || !page[u].empty();
    }
    if (!any) break;
    // The seconds stored for every unit go through the executor; a unit's seconds past the
    // others' (a store cut mid-second) feed only its own live compensation.
    std::size_t m = 0;
    if (common) {
      m = page[0].size();
      for (const auto& v : page) m = std::min(m, v.size());
      if (m < static_cast<std::size_t>(kPageRows)) common = false;
    }
    for (std::size_t i = 0; i < m; ++i) {
      const storage::SampleRow& r0 = page[0][i];
      const double t_s = r0.t_s;
      const bool gap = (r0.flags & model::flag::link_gap) != 0;
      // An earlier resume's gap (no wall time: nothing was read) held the profile clock whatever
      // the policy, as the resume that wrote it did.
      const bool away = gap && !std::isfinite(r0.wall_time) && (r0.flags & model::flag::missing) != 0;
      if (((gap && r.policy == LinkLossConfig::Policy::hold) || away) && run.updated) {
        run.held_s += t_s - run.prev_t_s;
      } else {
        profiles::Readings readings;
        readings.chamber_c = r0.chamber_c;
        for (std::size_t u = 0; u < units; ++u) readings.coils.push_back({page[u][i].t1_c, page[u][i].t2_c});
        run.last = run.executor->update(t_s - run.held_s, readings);
        run.updated = true;
      }
      run.prev_t_s = t_s;
      run.phase = run.last.phase;
      run.step = run.last.step_index;
      if (std::isfinite(r0.wall_time)) {
        r.wall_last = r0.wall_time;
        r.wall_last_t_s = t_s;
      }
      for (std::size_t u = 0; u < units; ++u) r.flagged[u] += page[u][i].flags != 0;
    }
    if (m > 0) {
      r.n += m;
      r.last_t_s = page[0][m - 1].t_s;
    }
    for (std::size_t u = 0; u < units; ++u)
      for (const auto& row : page[u]) run.live.step(u, row);
  }
  return {};
}

ApiResult<std::int64_t> Station::finish_resume(ResumeReplay replay, double now_wall_time, const json& command) {
  ActiveRun& run = replay.run;
  const std::int64_t run_id = run.id;
  // Decided again on the loop: what may have changed while the seconds were replayed.
  if (auto busy = station_busy()) return std::unexpected(*busy);
  if (recovery_error_) return std::unexpected(not_recovered(*recovery_error_));
  if (auto down = chamber_unavailable()) return std::unexpected(*down);
  if (auto rec = store_.get_run(run_id); !rec) {
    return std::unexpected(from_store(rec.error()));
  } else if (rec->run.state != RunState::interrupted) {
    return api_error(ErrorCode::bad_request, "run_id: run " + std::to_string(run_id) + " is " +
                                                 std::string(storage::to_string(rec->run.state)) +
                                                 "; only an interrupted run resumes");
  }
  if (run.last.finished || run.last.failed)
    return api_error(ErrorCode::bad_request, "run_id: run " + std::to_string(run_id) +
                                                 ": its profile had already ended; nothing to resume");
  const double wall_last = replay.wall_last.value_or(now_wall_time);
  const double wall_last_t_s = replay.wall_last_t_s;
  const double last_t_s = replay.last_t_s;
  // The time the bench was without the daemon, in run seconds: the run clock counts it. It is
  // measured from the last second read (the last stored with a wall time), so it is the same
  // whether an earlier resume's gap was stored whole, in part (killed while writing it) or not
  // at all: the gap ends where the run clock stands now, and only its seconds not yet stored are
  // added. A gap is written once.
  const double down_s = std::max(0.0, std::floor((now_wall_time - wall_last) * time_scale_));
  const double gap_from_s = last_t_s + 1.0;                                  // [from, to)
  const double gap_to_s = std::max(gap_from_s, wall_last_t_s + 1.0 + down_s);
  const double already_s = std::max(0.0, gap_from_s - (wall_last_t_s + 1.0));  // stored by an earlier resume
  const double add_s = gap_to_s - gap_from_s;
  // The gap's seconds as rows, flagged: every second of the run is in the store, none invented.
  // Written by the sample writer, off the loop for fogbenchd (one slice a transaction), before
  // any second the run reads after it.
  SampleGap gap{gap_from_s, gap_to_s, {}};
  for (std::size_t u = 0; u < run.serials.size(); ++u) {
    storage::SampleRow r;
    r.unit_index = static_cast<int>(u);
    r.t_s = gap_from_s;
    r.setpoint_c = run.last.setpoint_c;
    r.phase = storage::model_phase(run.last.phase);
    r.step = static_cast<int>(run.last.step_index);
    r.flags = model::flag::missing | model::flag::link_gap;
    // None: a gap restarts the compensators (no gap, resumed within the second: they go on).
    if (add_s > 0) r.compensated_dph = run.live.step(u, r);
    gap.rows.push_back(r);
  }
  run.held_s += add_s;  // the profile clock stood still through the gap (its stored part was replayed)
  // The counts go on from the store: every second stored flagged, the gap's included. The
  // frames lost and corrupt before the crash were only in the dead daemon's memory: they count
  // from here.
  run.quality.assign(run.serials.size(), {});
  for (std::size_t u = 0; u < run.quality.size(); ++u)
    run.quality[u].samples_flagged = (u < replay.flagged.size() ? replay.flagged[u] : 0) + static_cast<std::uint64_t>(add_s);
  run.prev_t_s = gap_to_s - 1.0;
  run.resume_at_s = gap_to_s;
  run.state = RunState::interrupted;
  run.link_down = true;  // so the first tick records the link as up again when it is
  if (!run_analysis_.contains(run_id)) run_analysis_[run_id] = config_.analysis;
  run_ = std::move(run);
  event(run_id, storage::EventKind::command, command, gap_from_s);
  // Recorded before the gap's rows are: what is to be stored, and what an earlier resume had
  // already stored of it (a resume killed while writing its gap).
  json fault = {{"resumed", true}, {"gap_from_s", gap_from_s}, {"gap_s", add_s}, {"gap_to_s", gap_to_s},
                {"profile_clock_s", run_->prev_t_s - run_->held_s}};
  if (already_s > 0) {
    fault["gap_stored_before_s"] = already_s;
    fault["gap_started_s"] = wall_last_t_s + 1.0;
  }
  event(run_id, storage::EventKind::fault, fault, gap_from_s);
  if (add_s > 0) samples_->append_gap(run_id, std::move(gap), clock_s_);
  return run_id;
}

ApiResult<std::int64_t> Station::abort_run(const std::string& reason, const json& command) {
  if (!run_) return api_error(ErrorCode::not_found, "no run is active");
  const auto id = run_->id;
  event(id, storage::EventKind::command, command, run_->elapsed_s);
  finish(RunState::aborted, reason);
  return id;
}

void Station::shutdown(const std::string& reason) {
  sample_drain_timeout_ = kStopSampleDrainTimeout;
  if (run_) finish(RunState::aborted, reason);
  setpoint_c_ = config_.safe_setpoint_c;
  // A last try for what the store refused; what it still refuses is lost with the process
  // (each was logged when it was refused).
  if (!journal_.empty()) journal_.flush();
  if (!journal_.empty())
    spdlog::error("stopping with {} state changes or events the store did not take (see above)", journal_.size());
}

// A run that fails on what it read (a settle that timed out, a chamber fault) after the loop
// fell behind real time: that is the first thing to know about it, since seconds never read
// make a settle time out and blame the chamber wrongly. An operator's abort, a shutdown or a
// full store are what they say.
std::string Station::behind_real_time(const ActiveRun& run, const std::string& why) const {
  if (run.late_s == 0) return why;
  // A chamber link lost before (or as) the loop fell behind is the first cause: the chamber's
  // calls wait out their reply timeouts and make the ticks late, not a busy host (issue 27,
  // point 4). A few seconds' grace: the call that times out makes its tick late before its
  // failure is known.
  constexpr double kLinkFailureKnownAfter_s = 3.0;
  if (run.link_down_since_s && run.first_late_s && *run.link_down_since_s <= *run.first_late_s + kLinkFailureKnownAfter_s) {
    std::ostringstream o;
    o << why << "; meanwhile " << run.late_s << " of " << run.elapsed_s + 1
      << " s were not read in time (the chamber's calls waited out their timeouts)";
    return o.str();
  }
  std::ostringstream o;
  o << "the acquisition fell behind real time (" << run.late_s << " of " << run.elapsed_s + 1
    << " s not read in time: the host is too busy for time scale " << time_scale_ << "); " << why;
  return o.str();
}

std::string Station::storage_reason(const SampleWriteFailure& f) {
  std::ostringstream o;
  o << (f.error.code == storage::StoreErrc::disk_full ? "storage full" : "storage failed") << " ("
    << storage::to_string(f.error.code) << "): samples could not be stored: " << f.error.message;
  return o.str();
}

void Station::finish(RunState to, const std::string& reason_in, EndCause cause) {
  assert(run_);
  ActiveRun& run = *run_;
  std::string reason = reason_in;
  // The run's samples first: its end is recorded after them, and a refusal among its last
  // seconds (the writer's thread reports it after the second was handed over) ends it aborted.
  const bool stalled = cause == EndCause::storage_stalled;
  const bool drained = samples_->drain(stalled ? std::chrono::milliseconds(0) : sample_drain_timeout_);
  if (auto lost = samples_->take_failure(); lost && lost->run_id == run.id) {
    if (WriteJournal::may_pass(lost->error.code)) journal_.set_refused(true);
    // A reason that is already the storage's (the tick took an earlier refusal) stays as it is.
    if (cause == EndCause::other)
      reason = to == RunState::aborted ? storage_reason(*lost) + "; the run was ending anyway: " + reason
                                       : storage_reason(*lost);
    to = RunState::aborted;
  } else if (!drained && !stalled) {  // a stall: the caller's reason already says it
    reason = "storage stalled: " + std::to_string(samples_->pending()) +
             " seconds of samples not committed yet (the store's disk does not answer); " + reason;
    to = RunState::aborted;
  }
  event(run.id, storage::EventKind::note, {{"quality", quality_json(run)}}, run.elapsed_s);
  transition(run, to, reason, run.elapsed_s);
  if (to != RunState::completed) spdlog::warn("run {} {}: {}", run.id, storage::to_string(to), reason);
  last_run_ = {{"run_id", run.id}, {"state", std::string(storage::to_string(to))}, {"reason", reason},
               {"elapsed_s", run.elapsed_s}};
  const auto id = run.id;
  const auto purpose = run.purpose;
  const auto serials = run.serials;
  run_.reset();
  setpoint_c_ = config_.safe_setpoint_c;
  rate_dps_ = 0.0;
  if (to == RunState::completed && !skip_analysis_.erase(id)) analyse(id, purpose, serials);
}

TickOutput Station::tick(double clock_s, const TickInput& in) {
  const TickOutput out = tick_station(clock_s, in);
  for (TickListener* l : tick_listeners_) l->after_tick(clock_s, in.wall_time);  // a plan's next step
  return out;
}

TickOutput Station::tick_station(double clock_s, const TickInput& in) {
  clock_s_ = clock_s;
  last_input_ = in;
  ++ticks_;
  // Both retries every 10 s of wall time: a store held locked makes each try wait out its busy
  // timeout (5 s), which must not hold up every second of the loop.
  if (!journal_.empty() && clock_s - unrecorded_tried_clock_s_ >= 10.0 * time_scale_) {
    unrecorded_tried_clock_s_ = clock_s;
    journal_.flush();
  }
  if (recovery_error_ && !run_ && clock_s - recovery_tried_clock_s_ >= 10.0 * time_scale_) {
    if (auto ids = recover(); ids) {
      for (auto id : *ids) spdlog::warn("run {} was in progress when the daemon stopped: marked interrupted", id);
      spdlog::info("the store took the interrupted marks; runs may start");
    }
  }
  // Power-ons and restarts of the gyros, from what their frames of this period say (anything
  // sent counts as sending: a corrupt frame is a gyro that is on). Never from the period's
  // timing: a late period holds no evidence.
  std::vector<std::optional<GyroEvidence>> sent(config_.drivers.units.size());
  for (std::size_t i = 0; i < sent.size() && i < in.units.size(); ++i)
    if (in.gyro_link_up)
      sent[i] = GyroEvidence{.frames = in.units[i].frames + in.units[i].frames_corrupt,
                             .starts = in.units[i].gyro_starts,
                             .read = in.gyro_read};
  const auto power_edges = power_.update(clock_s, sent);
  if (!run_) return {setpoint_c_, 0.0};
  ActiveRun& run = *run_;

  // A gyro's power-on, restart or lost power-on is an event of the run (and a unit's power-on
  // not seen is said at the start: its samples then carry no time since power-on).
  auto power_event = [&](std::size_t i, std::string_view what, double t_s) {
    const std::size_t ci = run.config_index[i];
    json detail = {{"gyro_power", what}, {"unit", static_cast<int>(i)}, {"serial", run.serials[i]}};
    if (auto since = power_.since_power_on_s(ci, clock_s)) detail["since_power_on_s"] = *since;
    event(run.id, storage::EventKind::note, detail, t_s);
  };
  if (run.state == RunState::pending) {
    run.start_clock_s = clock_s;
    transition(run, RunState::settling, "run started", 0.0);
    for (std::size_t i = 0; i < run.config_index.size(); ++i) {
      const std::size_t ci = run.config_index[i];
      if (ci < power_edges.size() && power_edges[ci] != PowerWatch::Edge::none) continue;  // said below
      if (!config_.drivers.units[ci].gyro.startup_flag && !power_.since_power_on_s(ci, clock_s)) {
        // A gyro kind whose frames carry no `warming_up` bit: a counter from 0 alone is what
        // frames lost of a running gyro also show, and silence is no evidence (a late reader),
        // so neither a power-on nor a power cycle can be known from its frames: said plainly,
        // once, rather than nothing.
        json detail = {{"gyro_power", "power_on_unknowable"}, {"unit", static_cast<int>(i)}, {"serial", run.serials[i]},
                       {"reason", "this gyro's frames carry no warm-up status bit (drivers.units[" + std::to_string(ci) +
                                      "].gyro.startup_flag false): its power-on and power cycles cannot be known from "
                                      "its frames; its samples carry no since_power_on_s"}};
        event(run.id, storage::EventKind::note, detail, 0.0);
        continue;
      }
      power_event(i, power_.since_power_on_s(ci, clock_s) ? "on" : "power_on_not_seen", 0.0);
    }
  } else if (run.state == RunState::interrupted) {
    // Resumed: the run clock goes on from the gap's end.
    run.start_clock_s = clock_s - *run.resume_at_s;
    transition(run, run.phase == profiles::Phase::settle ? RunState::settling : RunState::running,
               "resumed by operator", *run.resume_at_s);
  }
  run.elapsed_s = clock_s - run.start_clock_s;
  const double t_s = run.elapsed_s;
  if (in.late) {
    ++run.late_s;
    if (!run.first_late_s) run.first_late_s = t_s;
  }
  for (std::size_t i = 0; i < run.config_index.size(); ++i) {
    const std::size_t ci = run.config_index[i];
    if (ci < power_edges.size() && power_edges[ci] != PowerWatch::Edge::none) power_event(i, to_string(power_edges[ci]), t_s);
  }

  // The gyro transport's problems with its stream (a serial line's garbage, CRC errors, cut
  // frames, a wrong-baud silence), each naming the device: already a line a minute per kind.
  for (const auto& line : in.gyro_stream_events)
    event(run.id, storage::EventKind::fault, {{"gyro_stream", line}}, t_s);

  // Alarms and link faults are recorded on their edges, not every second.
  if (in.chamber_alarm != run.alarm) {
    run.alarm = in.chamber_alarm;
    event(run.id, storage::EventKind::alarm, {{"alarm", in.chamber_alarm}, {"source", "chamber"}}, t_s);
  }
  if (in.chamber_link_down != run.link_down) {
    run.link_down = in.chamber_link_down;
    event(run.id, storage::EventKind::fault,
          {{"chamber_link", in.chamber_link_down ? "down" : "up"}}, t_s);
  }

  // The chamber's faults are judged on what was commanded up to now (setpoint_c_), before
  // this second's profile step.
  std::optional<std::string> abort_reason = chamber_fault(run, in, t_s);
  // The rate table's, for a run that drives it: a fault or a lost link ends the run at once
  // (the table is then commanded to 0 deg/s, as the chamber to its safe setpoint).
  if (run.rates && !abort_reason) {
    if (auto why = table_fault(in)) {
      event(run.id, storage::EventKind::fault, {{"rate_table", *why}}, t_s);
      abort_reason = std::move(why);
    }
  }

  const bool gap = in.chamber_link_down;
  const bool hold = gap && config_.link_loss.policy == LinkLossConfig::Policy::hold && run.updated;
  // Under `hold` the profile clock stands still through a gap: the chamber cannot be told
  // anything, so the profile resumes where it was rather than jumping ahead.
  if (hold) run.held_s += t_s - run.prev_t_s;
  run.prev_t_s = t_s;
  profiles::ExecutorStatus st = run.last;
  if (!hold) {
    profiles::Readings readings;
    readings.chamber_c = in.chamber_c ? *in.chamber_c : std::nan("");
    for (std::size_t ci : run.config_index) {
      const UnitReading* u = ci < in.units.size() ? &in.units[ci] : nullptr;
      readings.coils.push_back({u && u->t1_c ? *u->t1_c : std::nan(""), u && u->t2_c ? *u->t2_c : std::nan("")});
    }
    st = run.executor->update(t_s - run.held_s, readings);
    run.last = st;
    run.updated = true;
  }

  if (run.state == RunState::settling && st.phase != profiles::Phase::settle && !st.failed)
    transition(run, RunState::running,
               run.phase == profiles::Phase::settle ? "settled" : "profile started", t_s);
  if (!run.phase || *run.phase != st.phase || run.step != st.step_index) {
    run.phase = st.phase;
    run.step = st.step_index;
    event(run.id, storage::EventKind::phase,
          {{"phase", std::string(profiles::to_string(st.phase))}, {"step", st.step_index},
           {"line", st.step_line}},
          t_s);
  }

  // The table's command this second, stored with every unit's row (rate_in_dps).
  const double rate_dps = run.rates ? run.rates->at(st).rate_dps : 0.0;
  std::vector<storage::SampleRow> rows;
  rows.reserve(run.config_index.size());
  if (run.quality.size() < run.config_index.size()) run.quality.resize(run.config_index.size());
  for (std::size_t i = 0; i < run.config_index.size(); ++i) {
    const std::size_t ci = run.config_index[i];
    const UnitReading u = ci < in.units.size() ? in.units[ci] : UnitReading{};
    rows.push_back(sample_row(static_cast<int>(i), u, in, t_s, st, run.pv_frozen, power_.since_power_on_s(ci, clock_s),
                              run.table_max_abs_dps));
    rows.back().compensated_dph = run.live.step(i, rows.back());
    if (run.rates) rows.back().rate_in_dps = rate_dps;
    run.quality[i].frames_lost += u.frames_lost;
    run.quality[i].frames_corrupt += u.frames_corrupt;
    run.quality[i].samples_flagged += rows.back().flags != 0;
    note_silent_axes(run, i, u, in, t_s);
    note_saturated_axes(run, i, u, t_s);
  }
  if (!run.live_noted) {
    run.live_noted = true;
    event(run.id, storage::EventKind::note, run.live.describe(), t_s);
  }
  for (const auto& r : rows) {
    const auto i = static_cast<std::size_t>(r.unit_index);
    emit(protocol::to_json(sample_message(r, run.id, run.serials[i], run.state, st, in.chamber_c,
                                          i < run.unit_axes.size() ? run.unit_axes[i] : 1)));
  }
  // Committed off the loop by fogbenchd's writer thread (sample_writer.hpp): a refusal is known
  // here at once with the inline writer, a second or a few later with the thread.
  samples_->append(run.id, std::move(rows), clock_s);
  auto lost = samples_->take_failure();
  if (lost && lost->run_id != run.id) lost.reset();  // an ended run's: logged by the writer
  const auto oldest = samples_->oldest_pending_clock_s();
  const bool stalled = oldest && (clock_s - *oldest) / time_scale_ > kSampleStallWall_s;

  if (lost) {
    // Samples that cannot be stored make the run worthless: stop it rather than run on blind,
    // and make the chamber safe. A fault of the station, as a chamber's is: `aborted`
    // (`failed` is a profile that could not be run, e.g. a settle that timed out). The run's
    // end that follows must not wait out the lock again (write_or_keep).
    if (WriteJournal::may_pass(lost->error.code)) journal_.set_refused(true);
    finish(RunState::aborted, storage_reason(*lost), EndCause::storage_refused);
  } else if (stalled) {
    // Not a wait on the loop: the run ends at once, its queued seconds committed if the disk
    // comes back. Its end is written through the journal like any refused write.
    journal_.set_refused(true);
    std::ostringstream o;
    o << "storage stalled: the sample of t_s " << (*oldest - run.start_clock_s) << " s is not committed after "
      << (clock_s - *oldest) / time_scale_ << " s of wall time (the store's disk does not answer)";
    finish(RunState::aborted, o.str(), EndCause::storage_stalled);
  } else if (abort_reason) {
    finish(RunState::aborted, behind_real_time(run, *abort_reason));
  } else if (st.failed) {
    finish(RunState::failed, behind_real_time(run, st.failure_reason));
  } else if (st.finished) {
    finish(RunState::completed, "profile finished");
  } else {
    setpoint_c_ = st.setpoint_c;
    rate_dps_ = rate_dps;
  }
  return {setpoint_c_, run_ ? rate_dps_ : 0.0};
}

std::optional<std::string> Station::table_fault(const TickInput& in) {
  if (!in.rate_table) return std::string("rate table: none is connected to drive the profile's rate steps");
  if (in.rate_table->fault) return "rate table fault: " + in.rate_table->reason;
  if (in.rate_table->link_down) return "rate table link lost: " + in.rate_table->reason;
  if (in.rate_table->unreadable) return "rate table status unreadable: " + in.rate_table->reason;
  return std::nullopt;
}

std::optional<std::string> Station::chamber_fault(ActiveRun& run, const TickInput& in, double t_s) {
  auto fmt = [](double v) {
    std::ostringstream o;
    o << v;
    return o.str();
  };
  // The controller's own alarm: it knows something is wrong with the chamber; a drift run
  // through it measures nothing useful.
  const bool alarm_rose = in.chamber_alarm && !run.alarm_seen;
  run.alarm_seen = in.chamber_alarm;
  if (alarm_rose) return std::string("chamber alarm");

  if (in.chamber_link_down) {
    if (!run.link_down_since_s) run.link_down_since_s = t_s;
    const double gap_s = t_s - *run.link_down_since_s;
    if (config_.link_loss.policy == LinkLossConfig::Policy::safe_abort)
      return std::string("chamber link lost (link_loss.policy safe_abort)");
    if (gap_s > config_.link_loss.tolerance_s)
      return "chamber link lost for " + fmt(gap_s) + " s (link_loss.tolerance_s " +
             fmt(config_.link_loss.tolerance_s) + ")";
    return std::nullopt;
  }
  run.link_down_since_s.reset();
  run.pv_frozen = false;
  if (!in.chamber_c) return std::nullopt;
  const double pv_c = *in.chamber_c;

  // Tracking is judged while running only: a settle waits for the chamber with its own timeout.
  const double err_c = std::abs(pv_c - setpoint_c_);
  if (run.state == RunState::running && err_c > config_.tracking.max_error_c) {
    if (!run.track_error_since_s) run.track_error_since_s = t_s;
    if (t_s - *run.track_error_since_s >= config_.tracking.for_s)
      return "chamber not following its setpoint: |PV - setpoint| " + fmt(err_c) + " degC for " +
             fmt(t_s - *run.track_error_since_s) + " s (tracking.max_error_c " +
             fmt(config_.tracking.max_error_c) + ", tracking.for_s " + fmt(config_.tracking.for_s) + ")";
  } else {
    run.track_error_since_s.reset();
  }

  // A PV that does not change at all while the setpoint moves is a frozen sensor or register,
  // not a slow chamber: a live PV changes in its last digit. A steady hold never trips it.
  if (!run.pv_last_c || pv_c != *run.pv_last_c) {
    run.pv_last_c = pv_c;
    run.pv_same_since_s = t_s;
    run.sp_min_c = run.sp_max_c = setpoint_c_;
  } else {
    run.sp_min_c = std::min(run.sp_min_c, setpoint_c_);
    run.sp_max_c = std::max(run.sp_max_c, setpoint_c_);
    // Unchanged while the setpoint moved this much: a stale value, flagged from here on (and
    // the run ends once it lasts tracking.frozen_s).
    run.pv_frozen = run.sp_max_c - run.sp_min_c >= kSetpointMovedC;
    if (t_s - run.pv_same_since_s >= config_.tracking.frozen_s && run.sp_max_c - run.sp_min_c >= kSetpointMovedC)
      return "chamber process value frozen at " + fmt(pv_c) + " degC for " + fmt(t_s - run.pv_same_since_s) +
             " s while the setpoint moved " + fmt(run.sp_max_c - run.sp_min_c) + " degC (tracking.frozen_s " +
             fmt(config_.tracking.frozen_s) + ")";
  }
  return std::nullopt;
}

}  // namespace fogbench::daemon
