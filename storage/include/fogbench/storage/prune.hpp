// Retention (store_prune.cpp, docs/storage.md "Retention"): Store::prune's options and report,
// Store::vacuum's report.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace fogbench::storage {

// Store::prune: the samples (every unit's seconds, the bulk of a store) of the runs that ended
// before a date are deleted; everything else a run has stays (its record, units, events,
// models, verifications, verdicts, certificates), and the run is marked pruned (RunRecord's
// pruned_at). By default only runs the plant store has received are pruned (docs/storage.md,
// "Retention").
struct PruneOptions {
  std::string before;                 // YYYY-MM-DD (midnight UTC) or YYYY-MM-DDTHH:MM:SSZ
  bool include_unreplicated = false;  // prune runs the plant store has not received too
  bool dry_run = false;               // say what would be pruned, change nothing
};

struct PrunedRun {
  std::int64_t run_id = 0;
  std::string ended_at;
  std::string state;                  // completed, aborted or failed
  std::vector<std::string> serials;   // by unit_index
  std::int64_t samples = 0;           // deleted (or, on a dry run, that would be)
  std::optional<std::string> sent_at; // when the plant store received it; empty: never
};

struct KeptRun {
  std::int64_t run_id = 0;
  std::string ended_at;
  std::string reason;                 // why it was not pruned
};

struct PruneReport {
  std::string before;                 // the cut-off as compared: YYYY-MM-DDTHH:MM:SS.000Z
  std::vector<PrunedRun> pruned;
  std::vector<KeptRun> kept;
  std::int64_t samples = 0;           // deleted in all
  bool dry_run = false;
};

// Store::vacuum: the file's size before and after, and the free space it was checked against.
struct VacuumReport {
  std::int64_t bytes_before = 0;  // the store file with its -wal
  std::int64_t bytes_after = 0;
  std::int64_t live_bytes = 0;    // the pages in use: what VACUUM copies, twice (temporary copy, WAL)
  std::int64_t free_bytes = 0;    // free on the store's filesystem before it ran
};

}  // namespace fogbench::storage
