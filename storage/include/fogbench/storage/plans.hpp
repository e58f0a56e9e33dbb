// Qualification plans, their queue and audit trail as stored (store_plans.cpp, docs/plans.md).
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace fogbench::storage {

// A qualification plan as stored (docs/plans.md): its text, units and the daemon's progress.
struct PlanRecord {
  std::int64_t id = 0;
  std::string name, source, plan_text;
  std::vector<std::string> units;  // serials
  std::string state;               // queued, running, completed, aborted, failed
  std::optional<std::int64_t> queue_pos;
  std::string created_at;
  std::optional<std::string> started_at, ended_at;
  std::string reason;
  std::string progress_json;
  // Who started it (operator_source: client, peer or none, as a run's identity) and each
  // unit's lot, given to every run of the plan (schema version 8).
  std::string operator_name = {}, operator_source = "none";
  std::map<std::string, std::string> lots = {};  // serial -> lot; a unit without a lot is absent
  // Each unit's bench slot (schema version 10); absent for plans stored before slots.
  std::map<std::string, std::string> slots = {};  // serial -> slot
};
struct NewPlan {
  std::string name, source, plan_text;
  std::vector<std::string> units;
  std::string state = "queued";  // or running
  std::string operator_name = {}, operator_source = "none";
  std::map<std::string, std::string> lots = {};  // serial -> lot
  std::map<std::string, std::string> slots = {};  // serial -> slot
};
// An entry of the plans' audit trail (queue edits, plan starts, steps, verdicts).
struct PlanEvent {
  std::int64_t id = 0;
  std::string at;
  std::optional<std::int64_t> plan_id;
  std::string kind, detail_json;
};

}  // namespace fogbench::storage
