// The station: one chamber, its units and the run in progress. It owns the run state machine
// (pending -> settling -> running -> completed | aborted | failed), turns each second's readings
// into stored samples, commands the setpoint from the profile executor, and fits or verifies
// models when a run completes. No I/O besides the store and no clock: the server passes the
// daemon time and the readings, so tests drive whole runs in milliseconds.
//
// Its rooms, one job each: the state machine and the tick (station.cpp), the profiles it may
// run (station_profiles.cpp), the status view (station_status.cpp), the end-of-run analysis
// (station_analysis.cpp, over the analysis service of analysis.hpp), the write journal
// (write_journal.hpp) and the pure building of a second's rows and messages (sample_rows.hpp).
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <deque>
#include <expected>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "fogbench/daemon/api.hpp"
#include "fogbench/daemon/bench_slots.hpp"
#include "fogbench/daemon/config.hpp"
#include "fogbench/daemon/live_compensation.hpp"
#include "fogbench/daemon/offload.hpp"
#include "fogbench/daemon/power_on.hpp"
#include "fogbench/daemon/run_control.hpp"
#include "fogbench/daemon/run_identity.hpp"
#include "fogbench/daemon/sample_writer.hpp"
#include "fogbench/daemon/tick_input.hpp"
#include "fogbench/daemon/write_journal.hpp"
#include "fogbench/profiles/executor.hpp"
#include "fogbench/profiles/profile.hpp"
#include "fogbench/profiles/rate_schedule.hpp"
#include "fogbench/protocol/protocol.hpp"
#include "fogbench/signing/signing.hpp"
#include "fogbench/storage/runs.hpp"
#include "fogbench/storage/verdict.hpp"

namespace fogbench::storage {
class Store;  // store.hpp: the station holds it by reference; a user of its calls includes it
}

namespace fogbench::daemon {

class PlanRunner;

struct TickOutput {
  double setpoint_c = 0.0;  // the setpoint the chamber should hold now
  // The rate the rate table should turn at now, deg/s: the active run's rate step
  // (profiles/rate_schedule.hpp), 0 (stopped) otherwise and from the second a run ends.
  double rate_dps = 0.0;
};

// The plan runner sees it through RunControl (run_control.hpp) only.
class Station final : public RunControl {
 public:
  // Called with each "sample" and "event" message as it happens (subscribers).
  using Publish = std::function<void(const nlohmann::json&)>;
  // UTC now, ISO 8601 (models' created_at). Tests inject a fixed one.
  using WallClock = std::function<std::string()>;

  Station(DaemonConfig config, storage::Store& store, double time_scale = 1.0,
          WallClock wall_clock = {});
  // Not copied or moved: offload_ may point at its own inline_offload_.
  Station(const Station&) = delete;
  Station& operator=(const Station&) = delete;

  void set_publisher(Publish p) { publish_ = std::move(p); }

  // Start-up: runs left in settling or running by a crash become interrupted. Should the store
  // refuse (a full disk, a lock held), the daemon runs on: the ticks try again every 10 s of
  // wall time while no run is active, and until it has worked no run starts or resumes (a new
  // run would be taken for one the crash left). status.recovery says why meanwhile.
  ApiResult<std::vector<std::int64_t>> recover();

  // Checks and creates a run in state pending; it starts at the next tick. `command` is the
  // request as received, stored as the run's first command event.
  // `op` is who started it, recorded in the run's identity with the station, the software, the
  // hashes of the configuration and the profile and each unit's power-on (run_identity.hpp).
  // `units`: each unit's slot and serial (bench_slots.hpp), stored with the run.
  ApiResult<std::int64_t> start_run_in_slots(const std::string& profile_name, const std::vector<SlotUnit>& units,
                                    storage::Purpose purpose, const nlohmann::json& command,
                                    const OperatorId& op) override;
  // The same with serials alone, each in the slot whose configured default serial it is
  // (unknown_serial when none is).
  ApiResult<std::int64_t> start_run(const std::string& profile_name,
                                    const std::vector<std::string>& serials,
                                    storage::Purpose purpose, const nlohmann::json& command,
                                    const OperatorId& op = {});
  // Takes up an interrupted run again (run.resume): the profile goes on from where its clock
  // stood at the last stored second (replayed from the stored samples, so settles decide as
  // they did), the run clock counts the time it was down, and the seconds of that gap are
  // stored flagged missing and link_gap, the profile clock held through them.
  // `now_wall_time` (unix s) measures the gap against the last stored sample's wall time.
  // Everything on the caller's thread, the stored seconds replayed on this station's store
  // (tests, the inline offload).
  ApiResult<std::int64_t> resume_run(std::int64_t run_id, double now_wall_time, const nlohmann::json& command);
  // The same with the replay of the stored seconds (every row of the run read and stepped
  // through the profile and the live compensation: 0.25 s of loop for 30,000 stored seconds of 2
  // units, 0.95 s for 300,000) done as a job on the offload (its worker in fogbenchd), so the loop
  // goes on meanwhile (issue 27, "nothing long runs on the loop"). The checks that need no rows
  // answer at once through `done`; the rest is decided back on the loop once replayed: the run
  // taken up with the gap measured at that moment (`now_wall_time` plus the steady time the
  // replay took). While one is replayed, run.start and another resume are refused `busy`.
  void resume_run_async(std::int64_t run_id, double now_wall_time, const nlohmann::json& command, JobOrigin origin,
                        ResumeDone done) override;
  // The run whose stored seconds are being replayed for a resume, if any.
  std::optional<std::int64_t> resuming_run_id() const override { return resuming_; }
  // Ends the active run as aborted; the chamber goes back to the safe setpoint at the next tick.
  ApiResult<std::int64_t> abort_run(const std::string& reason, const nlohmann::json& command) override;

  // One acquisition period: clock_s is the daemon's time in daemon seconds (k * 1 s at tick k).
  TickOutput tick(double clock_s, const TickInput& in);

  // The daemon is stopping: an active run ends as aborted with this reason.
  void shutdown(const std::string& reason);

  nlohmann::json status() const override;
  std::optional<std::int64_t> active_run_id() const override;
  // A run whose end the store could not take yet (a full disk): its state and reason as the
  // daemon knows them, {state, reason, recorded: false}; null for any other run.
  nlohmann::json unrecorded_end(std::int64_t run_id) const;
  // The active run's quality counters per unit (as in status), or null when run_id is not active.
  nlohmann::json live_quality(std::int64_t run_id) const;

  // Profiles: by name from the profile directory, or from text; limits checked.
  ApiResult<profiles::Profile> load_profile(const std::string& name, std::string* text) const override;
  ApiResult<profiles::Profile> check_profile_text(const std::string& text,
                                                  const std::string& source) const;
  std::vector<std::string> profile_names() const;

  // Where the analysis runs (the fit or verification when a run completes, and the handler's
  // fit, verify and workbench commands): inline on this station's store until the server gives
  // it its worker (offload.hpp). Not owned; it must outlive the station's use of it.
  void set_offload(Offload* offload) { offload_ = offload ? offload : &inline_offload_; }
  Offload& offload() { return *offload_; }
  // Where each second's samples are committed (sample_writer.hpp): inline on this station's
  // store until the server gives it its writer thread. Not owned; it must outlive the station's
  // use of it. Set before the first run starts.
  void set_sample_writer(SampleWriter* writer) { samples_ = writer ? writer : &inline_samples_; }
  // What the plant link is doing (status.plant's link fields: state, stalled, ...), from the
  // server's PlantLink; none: status shows the outbox only.
  void set_plant_link_state(std::function<nlohmann::json()> f) { plant_link_state_ = std::move(f); }
  // How long a run's end waits for its samples to be committed: the writer's own busy timeout
  // (5 s by default) and a slow fsync fit in it.
  static constexpr std::chrono::milliseconds kSampleDrainTimeout{15000};
  // The same at a stop (shutdown()): its share of the stop's budget below systemd's
  // TimeoutStopSec (docs/reliability.md "The stop's budget").
  static constexpr std::chrono::milliseconds kStopSampleDrainTimeout{4000};
  // A second the writer has not committed after this much wall time is a stalled store (a disk
  // that does not answer): the run ends aborted rather than acquire on blind.
  static constexpr double kSampleStallWall_s = 30.0;
  // The models' created_at: the injected wall clock's now.
  std::string wall_now() const { return wall_clock_(); }

  storage::Store& store() { return store_; }
  const DaemonConfig& config() const { return config_; }
  const std::vector<drivers::UnitConfig>& bench_units() const override { return config_.drivers.units; }
  // A configuration reload (config_reload.hpp) puts `next` in force: the server has kept every
  // key that needs a restart at its old value. The active run keeps its units' slots and the
  // analysis settings it started with; runs started afterwards take the new ones.
  void reload_config(DaemonConfig next) { config_ = std::move(next); }
  // Who reloads the configuration file for config.reload (the server); unset: unavailable.
  using Reloader = std::function<ApiResult<nlohmann::json>()>;
  void set_reloader(Reloader r) { reloader_ = std::move(r); }
  ApiResult<nlohmann::json> reload() {
    if (!reloader_) return api_error(ErrorCode::unavailable, "this daemon has no configuration file to reload");
    return reloader_();
  }
  // The key certificates are signed with (docs/daemon.md "The station key"): the server sets
  // the one of config().signing_key_path at start; until then (a station in a test) a key made
  // for this process alone, with no file (`signing_key_path()` empty).
  void set_signing_key(signing::SigningKey key, std::filesystem::path path) {
    signing_key_ = std::move(key);
    signing_key_path_ = std::move(path);
  }
  const signing::SigningKey& signing_key();
  const std::filesystem::path& signing_key_path() const { return signing_key_path_; }
  double time_scale() const { return time_scale_; }
  // Records an operator command in the audit trail of a run.
  void audit(std::int64_t run_id, const nlohmann::json& command);
  // Told after every tick, in the order added; not owned (the plan runner: it listens to the
  // ticks, the station never calls it).
  void add_tick_listener(TickListener* l) { tick_listeners_.push_back(l); }
  // The qualification plans' runner (plan_runner.hpp), where the handler finds it; not owned,
  // and never called by the station. None: the plan.* and queue.* commands answer unavailable.
  void set_plan_runner(PlanRunner* r) { plans_ = r; }
  PlanRunner* plan_runner() const { return plans_; }
  // The run (active, or resumed at the next tick) ends without the automatic fit or
  // verification: a plan's soak and custom steps (docs/plans.md). Forgotten at a restart.
  void skip_analysis(std::int64_t run_id) override { skip_analysis_.insert(run_id); }
  // Whether this process has submitted the automatic analysis of the run (in hand or done; its
  // notes may still wait in the journal). A completed run a plan waits on without it: the
  // daemon was killed between the run's end and its analysis, and the plan runner asks for it
  // again (analyse_units). One id per analysed run, kept for the process's life.
  bool analysing(std::int64_t run_id) const override { return analysing_.contains(run_id); }
  // The automatic analysis of a completed run's `units` only (indices into `serials`).
  void analyse_units(std::int64_t run_id, storage::Purpose purpose, const std::vector<std::string>& serials,
                     const std::vector<int>& units) override;
  // A serial's verdict decided (issue 24, one verdict: daemon/src/verdict.hpp): stored, the
  // serial's certificate issued again from it, then (queue_run) the deciding run queued for the
  // plant, so that it travels with its verdict and certificate. Returns the certificate's
  // sha256; an error when the verdict could not be stored, or the certificate not issued (a
  // serial without a model has none: not_found; the verdict stays).
  ApiResult<std::string> decide(const storage::NewVerdict& v, bool queue_run) override;

  // The units' lots from run.start's (or plan.start's, queue.add's) "lot" (every unit) or
  // "lots" ({serial: lot}), checked (station_plant.cpp); a unit without a lot is empty.
  static ApiResult<std::vector<std::optional<std::string>>> unit_lots(const nlohmann::json& command,
                                                                      const std::vector<std::string>& serials);

 private:
  struct ActiveRun {
    std::int64_t id = 0;
    storage::Purpose purpose = storage::Purpose::fit;
    std::string profile_name;
    std::vector<std::string> serials;
    std::vector<std::size_t> config_index;  // of each run unit in config_.drivers.units
    std::vector<std::string> slots;         // each run unit's slot name, as the run started
    storage::RunState state = storage::RunState::pending;
    std::unique_ptr<profiles::Executor> executor;
    // Per run unit: what the run lost, for status and the `quality` note stored at its end.
    struct Quality {
      std::uint64_t frames_lost = 0, frames_corrupt = 0, samples_flagged = 0;
    };
    std::vector<Quality> quality;
    std::int64_t late_s = 0;  // seconds the loop was too late to read (TickInput::late)
    std::optional<double> first_late_s;  // run time of the first of them
    double start_clock_s = 0.0;
    std::optional<double> resume_at_s;  // a resumed run: the run time of its first tick
    double elapsed_s = 0.0;
    profiles::ExecutorStatus last;
    std::optional<profiles::Phase> phase;
    std::size_t step = 0;
    bool alarm = false;
    bool alarm_seen = false;  // for chamber_fault: the alarm edge that aborts
    bool link_down = false;
    // The profile clock runs behind the run clock by the link gaps held (link_loss.policy hold).
    double held_s = 0.0;
    double prev_t_s = 0.0;
    bool updated = false;                       // the executor has been updated once
    std::optional<double> link_down_since_s;    // run time the current gap began
    std::optional<double> track_error_since_s;  // run time |PV - SP| went over max_error_c
    std::optional<double> pv_last_c;            // the PV as last seen changing ...
    double pv_same_since_s = 0.0;               // ... since this run time,
    double sp_min_c = 0.0, sp_max_c = 0.0;      // the setpoints commanded meanwhile
    bool pv_frozen = false;                     // this second's PV is a frozen one (flag pv_frozen)
    LiveCompensation live;                      // each unit's compensated rate (live_compensation.hpp)
    // The rate table's command over the run, from the profile's rate steps (set at the first
    // tick); empty: the run drives no table and stores no commanded rate.
    std::optional<profiles::RateSchedule> rates;
    // The largest |rate| of `rates`, deg/s (0 without): the out-of-range bound of every second's
    // gyro reading, computed once when the run starts or resumes.
    double table_max_abs_dps = 0.0;
    // Per run unit: its gyro axes (1 or 3) as the run started or was stored, not as the current
    // configuration says (a reload mid-run must not change a running run's axes).
    std::vector<int> unit_axes;
    bool live_noted = false;                    // its models are in the run's events
    // Per run unit, per axis (x, y, z): a second of silence of that axis is in the run's events
    // (said once per run, note_silent_axes).
    std::vector<std::array<bool, 3>> axis_silence_noted;
    // Per run unit, per axis: a second with frames at the int32 count limit is in the run's
    // events (said once per run, note_saturated_axes).
    std::vector<std::array<bool, 3>> axis_saturation_noted;
  };

  static nlohmann::json quality_json(const ActiveRun& run);
  // A resume in three steps (resume_run): the checks and the run's skeleton on the loop, the
  // replay of its stored seconds on any store and thread (it touches only the struct), the gap
  // and the take-over on the loop again.
  struct ResumeReplay {
    ActiveRun run;
    LinkLossConfig::Policy policy = LinkLossConfig::Policy::hold;
    std::size_t n = 0;                 // seconds stored for every unit
    std::optional<double> wall_last;   // the wall time of the last second the bench was read
    double wall_last_t_s = -1.0;       // its run second
    double last_t_s = -1.0;            // the last stored second
    std::vector<std::uint64_t> flagged;  // per unit: stored seconds flagged
  };
  ApiResult<ResumeReplay> begin_resume(std::int64_t run_id);
  static ApiResult<void> replay_stored(storage::Store& store, ResumeReplay& r);
  ApiResult<std::int64_t> finish_resume(ResumeReplay r, double now_wall_time, const nlohmann::json& command);
  // Why no run may start or be resumed now: a run active or a resume being replayed.
  std::optional<ApiError> station_busy() const;
  TickOutput tick_station(double clock_s, const TickInput& in);
  // Why no run may start now (the chamber link is down), if so.
  std::optional<ApiError> chamber_unavailable() const;
  // `why` a run fails or aborts for, said after the loop fell behind real time if it did.
  std::string behind_real_time(const ActiveRun& run, const std::string& why) const;
  // Why the chamber's state this second ends the run (alarm, link lost, not tracking), if it does.
  std::optional<std::string> chamber_fault(ActiveRun& run, const TickInput& in, double t_s);
  // Why the rate table's state this second ends a run that drives it (a fault it reports, its
  // link lost, none configured), if it does.
  static std::optional<std::string> table_fault(const TickInput& in);
  // A three-axis unit's axis that sent no frame this second while another of its axes did: the
  // first such second of each axis is a `fault` event naming the unit, the axis and its CAN id
  // (the seconds themselves are flagged missing, sample_rows.hpp).
  void note_silent_axes(ActiveRun& run, std::size_t unit, const UnitReading& u, const TickInput& in, double t_s);
  // An axis whose frames this second carried counts at the int32 limit (a rate beyond what the
  // unit's scale can carry: the reading is clipped): the first such second of each axis is a
  // `fault` event naming the unit, the axis, the time and the scale (the seconds themselves are
  // flagged out_of_range, sample_rows.hpp).
  void note_saturated_axes(ActiveRun& run, std::size_t unit, const UnitReading& u, double t_s);

  void transition(ActiveRun& run, storage::RunState to, const std::string& reason,
                  std::optional<double> t_s);
  // A state change or event: written through the journal, which keeps what the store refuses
  // (a full disk, an I/O error) and writes it again every 10 s of wall time until the store
  // takes it, so the audit trail ends up complete and in order once there is room.
  void write_or_keep(WriteJournal::Write w);
  void event(std::int64_t run_id, storage::EventKind kind, const nlohmann::json& detail,
             std::optional<double> t_s);
  // What ends a run, as finish() needs to know it: the storage's own reasons are not prefixed
  // again by a further refusal, and a stalled writer is not waited for.
  enum class EndCause { other, storage_refused, storage_stalled };
  // Ends the active run. Its samples are committed first (the sample writer drained, at most
  // kSampleDrainTimeout, not at all when it stalled), so its end is recorded after them and its
  // analysis reads every one; rows the store refused meanwhile end it aborted for the storage,
  // whatever `reason` was.
  void finish(storage::RunState to, const std::string& reason, EndCause cause = EndCause::other);
  // Why the store lost some of the run's seconds, as the run's end reason.
  static std::string storage_reason(const SampleWriteFailure& f);

  // The automatic fit or verification of a completed run: computed on the offload, stored and
  // noted (a `note` event per unit) back on the loop.
  void analyse(std::int64_t run_id, storage::Purpose purpose, const std::vector<std::string>& serials);
  void emit(const nlohmann::json& message) {
    if (publish_) publish_(message);
  }

  // The plant outbox (station_plant.cpp, issue 14).
  void queue_for_plant(std::int64_t run_id);
  nlohmann::json plant_status() const;

  DaemonConfig config_;
  storage::Store& store_;
  InlineOffload inline_offload_{store_};
  Offload* offload_ = &inline_offload_;
  InlineSampleWriter inline_samples_{store_};
  SampleWriter* samples_ = &inline_samples_;
  std::chrono::milliseconds sample_drain_timeout_ = kSampleDrainTimeout;  // a run's end (shutdown: shorter)
  std::function<nlohmann::json()> plant_link_state_;
  double time_scale_ = 1.0;
  WallClock wall_clock_;
  std::optional<signing::SigningKey> signing_key_;
  std::filesystem::path signing_key_path_;
  Publish publish_;
  std::optional<ActiveRun> run_;
  std::optional<std::int64_t> resuming_;  // a resume's stored seconds being replayed (resume_run_async)
  double setpoint_c_ = 0.0;      // the setpoint commanded now
  double rate_dps_ = 0.0;        // the rate table's rate commanded now, deg/s (0: stopped)
  double clock_s_ = 0.0;         // last tick's daemon time
  std::optional<TickInput> last_input_;
  // How the last run ended ({run_id, state, reason}), for status: a run ended by a fault is
  // reported even when the store could not take its final state (a full disk).
  nlohmann::json last_run_ = nullptr;
  WriteJournal journal_{store_};
  double unrecorded_tried_clock_s_ = 0.0;
  // Why recover() has not worked yet; empty once it has (or before it is first called).
  std::optional<std::string> recovery_error_;
  double recovery_tried_clock_s_ = 0.0;
  std::int64_t ticks_ = 0;
  // Each configured unit's power-on as seen in its frames, whether a run is active or not.
  PowerWatch power_;
  PlanRunner* plans_ = nullptr;
  std::vector<TickListener*> tick_listeners_;
  std::set<std::int64_t> skip_analysis_;
  std::set<std::int64_t> analysing_;
  // The analysis settings each run started (or resumed) with: its automatic fit or verification
  // uses them, whatever a reload changed meanwhile (one verdict, by one rule).
  std::map<std::int64_t, AnalysisConfig> run_analysis_;
  Reloader reloader_;
};

// ISO 8601 UTC now, to the second.
std::string iso8601_now();

}  // namespace fogbench::daemon
