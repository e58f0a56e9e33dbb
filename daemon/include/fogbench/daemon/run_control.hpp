// What the plan runner (plan_runner.hpp) may ask of the station about runs (issue 26, point 3):
// the station implements it, the plan runner holds it instead of the whole Station, so that it
// knows nothing else of the station and can be driven in a test by a fake. Every call is made
// on the daemon's loop only (the thread that ticks the station and serves the socket), never
// from the analysis worker or the sample writer; none of them blocks on the chamber.
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "fogbench/daemon/api.hpp"
#include "fogbench/daemon/bench_slots.hpp"
#include "fogbench/daemon/offload.hpp"
#include "fogbench/daemon/run_identity.hpp"
#include "fogbench/drivers/config.hpp"
#include "fogbench/profiles/profile.hpp"
#include "fogbench/storage/runs.hpp"
#include "fogbench/storage/verdict.hpp"

namespace fogbench::daemon {

class RunControl {
 public:
  virtual ~RunControl() = default;
  // Default arguments are declared here only: a caller gets the defaults of the type it calls
  // through, so an override (Station's) declares none, and one called through Station passes
  // every argument.

  // A profile by name from the profile directory, its limits checked against the chamber's.
  virtual ApiResult<profiles::Profile> load_profile(const std::string& name, std::string* text = nullptr) const = 0;
  // The configured bench slots (drivers.units of the configuration in force).
  virtual const std::vector<drivers::UnitConfig>& bench_units() const = 0;
  // The run in progress (pending, settling or running), if any.
  virtual std::optional<std::int64_t> active_run_id() const = 0;
  // The station's status (the status command's result; its "run" is the active run's).
  virtual nlohmann::json status() const = 0;
  // Checks and creates a run in state pending (it starts at the next tick); `command` is
  // stored as its first command event, `op` in its identity. busy while a run is active,
  // unavailable while the store has not recovered: both worth trying again at a later tick.
  virtual ApiResult<std::int64_t> start_run_in_slots(const std::string& profile_name, const std::vector<SlotUnit>& units,
                                                     storage::Purpose purpose, const nlohmann::json& command,
                                                     const OperatorId& op) = 0;
  // Takes up an interrupted (or pending) run again, as run.resume; `now_wall_time` in unix s.
  // The replay of its stored seconds runs off the loop (a job of `origin`'s class); `done` is
  // called on the loop with the run id or why not (busy or unavailable: worth trying again).
  using ResumeDone = std::function<void(ApiResult<std::int64_t>)>;
  virtual void resume_run_async(std::int64_t run_id, double now_wall_time, const nlohmann::json& command, JobOrigin origin,
                                ResumeDone done) = 0;
  // The run whose stored seconds are being replayed for a resume, if any.
  virtual std::optional<std::int64_t> resuming_run_id() const = 0;
  // Ends the active run as aborted (the chamber to its safe setpoint at the next tick).
  virtual ApiResult<std::int64_t> abort_run(const std::string& reason, const nlohmann::json& command) = 0;
  // The run (active, or resumed at the next tick) ends without its automatic analysis. Called
  // right after start_run_in_slots or resume_run returned it.
  virtual void skip_analysis(std::int64_t run_id) = 0;
  // Whether this process has submitted the run's automatic analysis (in hand or done).
  virtual bool analysing(std::int64_t run_id) const = 0;
  // The automatic analysis of a completed run's `units` (indices into `serials`) submitted
  // again: for a run whose analysis this process never submitted (analysing() false).
  virtual void analyse_units(std::int64_t run_id, storage::Purpose purpose, const std::vector<std::string>& serials,
                             const std::vector<int>& units) = 0;
  // A serial's verdict stored and its certificate issued again (then, queue_run, the deciding
  // run queued for the plant); the certificate's sha256, not_found for a serial without a model.
  virtual ApiResult<std::string> decide(const storage::NewVerdict& v, bool queue_run) = 0;
};

}  // namespace fogbench::daemon
