// A run's records in the store: its state, purpose, units, audit events and the filter
// Store::list_runs takes (store.cpp).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "fogbench/storage/identity.hpp"

namespace fogbench::storage {

enum class RunState { pending, settling, running, completed, aborted, failed, interrupted };
std::string_view to_string(RunState s);
std::optional<RunState> run_state_from_string(std::string_view s);
// completed, aborted, failed and interrupted: the run has ended.
bool is_terminal(RunState s);

// Why a run was recorded: to fit a model, or to verify one.
enum class Purpose { fit, verify };
std::string_view to_string(Purpose p);
std::optional<Purpose> purpose_from_string(std::string_view s);

enum class EventKind { state, phase, command, alarm, fault, note };
std::string_view to_string(EventKind k);
std::optional<EventKind> event_kind_from_string(std::string_view s);

struct NewRun {
  std::string profile_name;
  std::string profile_text;              // the profile source, as run
  Purpose purpose = Purpose::fit;
  std::string config_json = "{}";        // the configuration in force (JSON object text)
  double time_scale = 1.0;               // profile seconds per wall second (1 on hardware)
  std::vector<std::string> unit_serials; // unit_index = position in this list
  std::optional<RunIdentity> identity;   // stored in the same transaction (identity.hpp)
  // Each unit's lot id (same positions; shorter or empty: no lot), 1..64 characters.
  std::vector<std::optional<std::string>> unit_lots;
  // Each unit's bench slot (same positions; shorter or empty: none), 1..16 characters.
  std::vector<std::string> unit_slots;
  // Each unit's gyro axes, 1 or 3 (same positions; shorter or empty: 1).
  std::vector<int> unit_axes;
};

struct RunUnit {
  int unit_index = 0;
  std::string serial;
  std::optional<std::string> lot;  // the production lot the unit came from, when given
  std::optional<std::string> slot; // the bench slot it sat in; empty for runs stored before slots
  int axes = 1;                    // its gyro axes: 3 stores gyro_y_dph and gyro_z_dph
};

struct RunRecord {
  std::int64_t id = 0;
  std::string created_at;                 // ISO 8601 UTC
  std::string profile_name;
  std::string profile_text;
  Purpose purpose = Purpose::fit;
  RunState state = RunState::pending;
  std::string state_reason;
  std::string config_json;
  std::optional<std::string> started_at;  // first entry into settling or running
  std::optional<std::string> ended_at;    // entry into a terminal state
  double time_scale = 1.0;
  std::vector<RunUnit> units;             // by unit_index
  std::optional<std::string> pruned_at;   // when Store::prune deleted its samples (ISO 8601 UTC)
  std::int64_t pruned_samples = 0;        // how many it deleted
};

struct RunEvent {
  std::int64_t id = 0;
  std::int64_t run_id = 0;
  std::optional<double> t_s;  // s since the run's start; empty for events outside the run clock
  std::string at;             // ISO 8601 UTC
  EventKind kind = EventKind::note;
  std::string detail_json;
};

struct RunDetail {
  RunRecord run;
  std::vector<RunEvent> events;  // in the order they were added
};

struct RunFilter {
  std::optional<RunState> state;
  std::optional<Purpose> purpose;
  std::optional<std::string> serial;        // runs that recorded this unit
  std::optional<std::string> profile_name;
  std::int64_t limit = 100;                 // newest first
  std::int64_t offset = 0;
};

}  // namespace fogbench::storage
