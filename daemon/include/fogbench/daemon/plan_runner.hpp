// Qualification plans run by the daemon (docs/plans.md): a plan is one job for the units
// loaded. After every tick the runner looks at the station: it starts the next step's run when
// the chamber is free, resumes the step's run after a restart (the run.resume mechanism), waits
// for the run's automatic fit or verification, judges each unit's measurements against the
// plan's limits (a stop-limit drops the unit, continue marks it marginal, retest runs the step
// once more for it), and at the end gives each unit its verdict. Its whole state is the plan's
// progress in the store, rewritten at each change, so a restart takes it up where it stood.
// The queue: plans waiting for the chamber; the first starts when no run or plan is active.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "fogbench/daemon/api.hpp"
#include "fogbench/daemon/bench_slots.hpp"
#include "fogbench/daemon/run_control.hpp"
#include "fogbench/daemon/run_identity.hpp"
#include "fogbench/daemon/tick_input.hpp"
#include "fogbench/plans/plan.hpp"
#include "fogbench/storage/store.hpp"

namespace fogbench::daemon {

// Who starts a plan and the lot of each of its units (issue 24): stored with the plan and given
// to every run it starts (each run's identity names the operator, each unit of it its lot).
struct PlanTrace {
  OperatorId op;
  std::map<std::string, std::string> lots;  // serial -> lot; a unit without a lot is absent
  // serial -> bench slot (bench_slots.hpp); a unit absent sits in the slot whose configured
  // default serial it is.
  std::map<std::string, std::string> slots;
};
// The trace as the plan's JSON shows it: {operator, operator_source, lots}.
nlohmann::json plan_trace_json(const std::string& operator_name, const std::string& operator_source,
                               const std::map<std::string, std::string>& lots);

class PlanRunner final : public TickListener {
 public:
  // `runs`: the station's runs (run_control.hpp); `store`: the station's store, where the plans
  // and their progress are kept (and the runs read). Neither owned: both outlive the runner.
  PlanRunner(RunControl& runs, storage::Store& store) : runs_(runs), store_(store) {}

  // Parses the plan and checks it against the station: every step's profile exists and is
  // within the chamber's limits, the units are configured, and a verify step that no fit step
  // precedes has a model on file for every unit. Errors name the line (and the field).
  ApiResult<plans::Plan> check(const std::string& text, const std::string& source,
                               const std::vector<std::string>& units,
                               const std::map<std::string, std::string>& slots = {}) const;
  // The configured bench slots, for plan.* and queue.* to read `slots` against.
  const std::vector<drivers::UnitConfig>& bench_slots() const;
  // plan.validate: the check's summary ({name, steps, limits, nominal_duration_s}).
  ApiResult<nlohmann::json> validate(const std::string& text, const std::string& source,
                                     const std::vector<std::string>& units,
                                     const std::map<std::string, std::string>& slots = {}) const;
  // plan.start: checked, stored as running; its first run starts at the next tick. Refused
  // (busy) while a run or another plan is active: queue it instead.
  ApiResult<nlohmann::json> start(const std::string& text, const std::string& source,
                                  const std::vector<std::string>& units, const PlanTrace& trace,
                                  const nlohmann::json& command);
  // plan.status: the plan (the running one, else the last one that started, when id is empty).
  ApiResult<nlohmann::json> status(std::optional<std::int64_t> plan_id) const;
  // plan.abort: the running plan ends aborted, its active run too.
  ApiResult<nlohmann::json> abort(const std::string& reason, const nlohmann::json& command);

  ApiResult<nlohmann::json> queue_list() const;
  ApiResult<nlohmann::json> queue_add(const std::string& text, const std::string& source,
                                      const std::vector<std::string>& units, const PlanTrace& trace,
                                      const nlohmann::json& command);
  ApiResult<nlohmann::json> queue_remove(std::int64_t plan_id, const nlohmann::json& command);
  // Moves a queued plan to `position` (1 = next).
  ApiResult<nlohmann::json> queue_move(std::int64_t plan_id, std::int64_t position, const nlohmann::json& command);

  // After every station tick (the daemon time and the tick's wall time, unix s): it listens to
  // the station's ticks (Station::add_tick_listener).
  void after_tick(double clock_s, double wall_time) override;

  std::optional<std::int64_t> running_plan_id() const;

  // A configuration reload's slots (`next`, drivers.units) against the plans not yet done
  // (running and queued): why the reload is refused when a unit of one would sit in another
  // bench position, or in none, at its next step (a plan names each unit's slot when accepted:
  // that slot renamed or removed); nullopt when every unit keeps its position.
  std::optional<std::string> slot_change_refusal(const std::vector<drivers::UnitConfig>& next) const;

 private:
  // One pass of the running plan's state machine; returns whether it changed something.
  bool advance(std::int64_t plan_id, double wall_time);
  // The verdicts of the completed run's units, per the limits; updates progress.
  void judge(std::int64_t plan_id, nlohmann::json& progress, const plans::Plan& plan, const nlohmann::json& run_detail_events,
             std::int64_t run_id);
  // The unit's verdict, final: stored as the serial's one verdict (Station::decide), once.
  void decide_unit(std::int64_t plan_id, nlohmann::json& progress, nlohmann::json& unit);
  void finish_plan(std::int64_t plan_id, nlohmann::json& progress, const std::string& state,
                   const std::string& reason);
  void save(std::int64_t plan_id, const std::string& state, const std::string& reason,
            const nlohmann::json& progress);
  void plan_event(std::optional<std::int64_t> plan_id, const std::string& kind, const nlohmann::json& detail);

  RunControl& runs_;
  storage::Store& store_;
  double last_queue_look_s_ = -1e300;
};

// The socket commands plan.* and queue.* (docs/protocol.md), for the handler's command table
// (handler.cpp), which names each one's access. `runner` is null on a station that runs no
// plans; `cmd` is the command's name, for the messages. plan.start and queue.add take the
// session's unix peer user too: the operator when the request names none (as run.start).
using PlanCommand = ApiResult<nlohmann::json> (*)(PlanRunner* runner, const std::string& cmd, const nlohmann::json& req);
using PlanStartCommand = ApiResult<nlohmann::json> (*)(PlanRunner* runner, const std::string& cmd,
                                                       const nlohmann::json& req, const std::string& peer_user);
ApiResult<nlohmann::json> plan_validate(PlanRunner* runner, const std::string& cmd, const nlohmann::json& req);
ApiResult<nlohmann::json> plan_start(PlanRunner* runner, const std::string& cmd, const nlohmann::json& req,
                                     const std::string& peer_user);
ApiResult<nlohmann::json> plan_status(PlanRunner* runner, const std::string& cmd, const nlohmann::json& req);
ApiResult<nlohmann::json> plan_abort(PlanRunner* runner, const std::string& cmd, const nlohmann::json& req);
ApiResult<nlohmann::json> queue_list(PlanRunner* runner, const std::string& cmd, const nlohmann::json& req);
ApiResult<nlohmann::json> queue_add(PlanRunner* runner, const std::string& cmd, const nlohmann::json& req,
                                    const std::string& peer_user);
ApiResult<nlohmann::json> queue_remove(PlanRunner* runner, const std::string& cmd, const nlohmann::json& req);
ApiResult<nlohmann::json> queue_move(PlanRunner* runner, const std::string& cmd, const nlohmann::json& req);

}  // namespace fogbench::daemon
