// The SQLite store of a fogbench station: runs, their units, samples and audit events, fitted
// models and verifications. Schema, migrations and durability are described in docs/storage.md.
//
// Thread safety: a Store is one SQLite connection opened without SQLite's mutexes; use it
// from one thread at a time (one Store per thread is fine: several Stores, in one or several
// processes, may open the same file; WAL lets readers run beside the one writer, and a
// writer waits up to OpenOptions::busy_timeout_ms for another).
#pragma once

#include <chrono>
#include <cstdint>
#include <expected>
#include <filesystem>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "fogbench/model/run.hpp"
#include "fogbench/storage/identity.hpp"
#include "fogbench/storage/verdict.hpp"

namespace fogbench::storage {

namespace detail {
class Database;  // the connection and its statement cache (storage/src/sqlite.hpp)
}

enum class StoreErrc {
  open_failed,       // the file cannot be opened or created
  not_fogbench,      // a SQLite database that is not a fogbench store
  schema_too_new,    // written by a newer fogbench: refused, never modified
  schema_too_old,    // opened read-only but it needs a migration
  migration_failed,  // a migration script failed; the database keeps its old version
  not_found,         // no such run, unit, model
  invalid_argument,  // a caller's value is unusable: bad JSON, unequal column lengths, NaN time
  constraint,        // a uniqueness or reference violated, e.g. a sample time stored twice
  read_only,         // SQLITE_READONLY: a read-only file, directory or connection
  disk_full,         // SQLITE_FULL: the disk (or OpenOptions::size_limit_bytes) is full
  io,                // SQLITE_IOERR
  busy,              // SQLITE_BUSY or SQLITE_LOCKED after the busy timeout
  corrupt,           // SQLITE_CORRUPT or SQLITE_NOTADB
  sqlite,            // any other SQLite failure
  pruned,            // the run's samples were deleted by Store::prune (its record stays)
};
std::string_view to_string(StoreErrc code);

struct StoreError {
  StoreErrc code = StoreErrc::sqlite;
  int sqlite_code = 0;  // SQLite's extended result code; 0 when the error is not SQLite's
  std::string message;  // what was being done, in which file, and SQLite's own message
};

template <class T>
using StoreResult = std::expected<T, StoreError>;

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

struct OpenOptions {
  // Open without any write (no migration, no journal-mode change); every write fails with
  // StoreErrc::read_only. A database that needs a migration is refused (schema_too_old).
  bool read_only = false;
  // Create the file when missing (ignored when read_only).
  bool create = true;
  // synchronous=FULL: every committed transaction is on disk when it returns, so a power cut
  // loses at most the call in progress. With false (NORMAL) a power cut may also lose
  // transactions committed since the last WAL checkpoint; a process crash loses nothing
  // committed either way. FULL costs one fsync per append_samples call (see the benchmark).
  bool synchronous_full = true;
  // How long a write waits for another connection's write lock before failing with `busy`.
  int busy_timeout_ms = 5000;
  // Refuse to grow the store beyond this size: writes then fail with disk_full. A guard for a
  // shared disk, and how the tests provoke SQLITE_FULL. It counts the files on disk: the
  // database, its write-ahead log (a quarter of the limit at most, 4 MiB at most, checkpointed
  // into the file when half full) and the WAL index (-shm, 32 KiB), see docs/storage.md.
  std::optional<std::int64_t> size_limit_bytes;
  // The mode a new database file is created with (its -wal and -shm get the same from SQLite),
  // set with fchmod so the umask does not matter. A file that exists keeps its mode.
  unsigned file_mode = 0640;
  // Before migrating a file on disk from an older schema N, copy it to `<path>.schema-<N>.bak`
  // (the way back to the fogbench that wrote it, docs/storage.md "Upgrade and downgrade"); a
  // copy that cannot be made refuses the migration (migration_failed) and leaves the file as it was.
  bool backup_before_migration = true;
  // The source of created_at and event times (ISO 8601 UTC); system_clock::now when empty.
  std::function<std::chrono::system_clock::time_point()> clock;
};

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
};

struct RunUnit {
  int unit_index = 0;
  std::string serial;
  std::optional<std::string> lot;  // the production lot the unit came from, when given
  std::optional<std::string> slot; // the bench slot it sat in; empty for runs stored before slots
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

inline constexpr double kNoValue = std::numeric_limits<double>::quiet_NaN();

// One second of one unit, as the daemon records it. A NaN double is stored as NULL (a signal
// not read) and read back as NaN.
struct SampleRow {
  int unit_index = 0;
  double t_s = 0;                      // s since the run's start; unique per unit
  double wall_time = kNoValue;         // unix time, s
  double setpoint_c = kNoValue;        // chamber setpoint, degC
  double chamber_c = kNoValue;         // chamber air, degC
  double gyro_dph = kNoValue;          // gyro output, deg/h
  std::optional<std::int64_t> frames;  // gyro frames received for this sample
  double t1_c = kNoValue;              // coil-centre thermistor, degC
  double t2_c = kNoValue;              // coil outer-wall thermistor, degC
  model::Phase phase = model::Phase::unknown;
  std::optional<int> step;             // profile step index
  std::uint8_t flags = 0;              // model::flag bits
  double since_power_on_s = kNoValue;  // time since the gyro's last power-on as the daemon saw
                                       // it, s; kNoValue when it did not see one
  // The daemon's live compensation of this second: gyro_dph minus the drift the unit's model
  // computed in its firmware form (model/firmware.hpp), deg/h; kNoValue when there was none
  // (no model, warming up, inputs missing; docs/daemon.md "Live compensation").
  double compensated_dph = kNoValue;
};

struct ExportOptions {
  // By default the leading settle samples are left out: the run proper starts after them.
  bool include_settle = false;
};

struct ImportOptions {
  std::string serial;                 // the unit's serial (required)
  std::string profile_name = "import";
  Purpose purpose = Purpose::fit;
  std::string config_json = "{}";
  std::string profile_text;                // the profile as run, when known
  std::optional<RunIdentity> identity;     // e.g. read back from the CSV's comments
  // The unit's production lot (a CSV export's `# lot:` line, lot_from_fields), 1..64 bytes of
  // printable text; none: the run has no lot, as a run started without one.
  std::optional<std::string> lot;
};

struct NewModel {
  std::string serial;
  std::optional<std::int64_t> run_id;     // the run it was fitted on
  std::optional<std::int64_t> parent_id;  // the model it refines
  std::string model_json;                 // opaque to storage, but must be JSON
  std::string method;
  std::string terms;
};

struct ModelRef {
  std::int64_t id = 0;
  int version = 0;  // 1, 2, 3... per serial
};

struct ModelRecord {
  std::int64_t id = 0;
  std::string serial;
  int version = 0;
  std::optional<std::int64_t> run_id;
  std::optional<std::int64_t> parent_id;
  std::string created_at;
  std::string model_json;
  std::string method;
  std::string terms;
};

struct NewVerification {
  std::int64_t run_id = 0;
  int unit_index = 0;
  std::int64_t model_id = 0;
  std::string result_json;
  bool pass = false;
};

struct VerificationRecord {
  std::int64_t id = 0;
  std::int64_t run_id = 0;
  int unit_index = 0;
  std::int64_t model_id = 0;
  std::string created_at;
  std::string result_json;
  bool pass = false;
};

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

// One run waiting in the plant outbox.
struct OutboxEntry {
  std::int64_t id = 0;
  std::int64_t run_id = 0;
  std::string queued_at;    // ISO 8601 UTC
  int attempts = 0;         // failed attempts so far
  std::string last_error;   // the last attempt's error, "" when none failed
};

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

struct OutboxStatus {
  std::int64_t depth = 0;                     // entries waiting
  std::optional<std::string> oldest_queued_at;
  int attempts = 0;                           // failed attempts of the oldest entry
  std::string last_error;                     // and its last error
  std::optional<std::string> last_sent_at;    // the last entry the plant committed
  std::int64_t sent = 0;                      // entries sent, ever
};

class Store {
 public:
  // Opens (creating when allowed) and migrates the database at `path` (":memory:" for a
  // private in-memory one). A newer schema or a foreign database is refused untouched.
  static StoreResult<Store> open(const std::filesystem::path& path, const OpenOptions& options = {});

  Store(Store&&) noexcept;
  Store& operator=(Store&&) noexcept;
  Store(const Store&) = delete;
  Store& operator=(const Store&) = delete;
  ~Store();

  static int current_schema_version();
  int schema_version() const;
  const std::filesystem::path& path() const;

  // --- runs and their audit trail
  // A new run in state pending, with its units and a first 'state' event.
  StoreResult<std::int64_t> create_run(const NewRun& run);
  // Sets the state and reason, stamps started_at/ended_at, and appends a 'state' event
  // {"from","to","reason"} in the same transaction. Transitions are the daemon's business:
  // any state may follow any other.
  StoreResult<void> set_run_state(std::int64_t run_id, RunState state, std::string_view reason,
                                  std::optional<double> t_s = std::nullopt);
  // Appends an event; detail_json must be JSON ("" is taken as {}). Returns the event id.
  StoreResult<std::int64_t> add_event(std::int64_t run_id, EventKind kind,
                                      std::string_view detail_json,
                                      std::optional<double> t_s = std::nullopt);
  StoreResult<std::vector<RunRecord>> list_runs(const RunFilter& filter = {});
  StoreResult<RunDetail> get_run(std::int64_t run_id);
  // Runs left in settling or running (by a crash) become interrupted, with `reason` and a
  // 'state' event at the last sample's t_s. Returns their ids, oldest first.
  StoreResult<std::vector<std::int64_t>> mark_interrupted_runs(std::string_view reason);

  // --- samples
  // Stores the rows in one transaction: all or none. The daemon calls this once a second, so a
  // crash loses at most the second being written. A t_s already stored for that unit, or an
  // unknown unit, is a constraint error and nothing of the call is kept.
  StoreResult<void> append_samples(std::int64_t run_id, std::span<const SampleRow> rows);
  // Samples of the run (of one unit when given).
  StoreResult<std::int64_t> count_samples(std::int64_t run_id,
                                          std::optional<int> unit_index = std::nullopt);
  // One page of a unit's samples in time order.
  StoreResult<std::vector<SampleRow>> get_samples(std::int64_t run_id, int unit_index,
                                                  std::int64_t offset, std::int64_t limit);

  // --- runs as model input
  // The unit's samples as RunData (name "run 12 unit 0 (FOG-0042)"), time_s as stored. An
  // optional column is filled when any exported sample has it (gaps: NaN, unknown, step -1,
  // flags 0) and left empty otherwise, so import_run -> export_run gives back the columns
  // imported. No samples to export is a not_found error.
  StoreResult<model::RunData> export_run(std::int64_t run_id, int unit_index,
                                         const ExportOptions& options = {});
  // Stores a run from a CSV (or any RunData) as a completed run with one unit (index 0), in one
  // transaction. Returns the new run's id.
  StoreResult<std::int64_t> import_run(const model::RunData& data, const ImportOptions& options);

  // --- models and verifications
  // Stores a model as the next version for its serial.
  StoreResult<ModelRef> put_model(const NewModel& m);
  StoreResult<ModelRecord> get_model(std::int64_t model_id);
  // The highest version for the serial; empty when it has none.
  StoreResult<std::optional<ModelRecord>> current_model(std::string_view serial);
  // Every version for the serial, oldest first.
  StoreResult<std::vector<ModelRecord>> list_models(std::string_view serial);
  // The model, its parent, its parent's parent... up to the root.
  StoreResult<std::vector<ModelRecord>> model_lineage(std::int64_t model_id);
  StoreResult<std::int64_t> put_verification(const NewVerification& v);
  StoreResult<std::vector<VerificationRecord>> list_verifications(std::int64_t run_id);

  // --- identity and certificates (store_identity.cpp)
  // The run's identity; empty for a run recorded without one (before schema 4, or imported
  // from a CSV without identity comments). A missing run is not_found.
  StoreResult<std::optional<RunIdentity>> get_run_identity(std::int64_t run_id);
  // Stores a certificate (its JSON must be JSON, its model the serial's). Returns its id.
  StoreResult<std::int64_t> put_certificate(const NewCertificate& c);
  // Certificates with this hash (normally none or one), oldest first.
  StoreResult<std::vector<CertificateRecord>> find_certificates(std::string_view sha256);
  // The serial's certificates, oldest first.
  StoreResult<std::vector<CertificateRecord>> list_certificates(std::string_view serial);
  // --- verdicts (store_verdicts.cpp, verdict.hpp): one row per decision, the serial's verdict
  // its latest. Checked: a known verdict and rule, a plan's id/name/hash with rule plan only,
  // JSON arrays, the run's unit holding the serial, the model the serial's. Returns its id.
  // The same decision again (the serial's latest row equal to it in every field but its time)
  // is not written twice: its row's id is returned (a plan runner killed between its decide
  // and its progress save decides again on restart).
  StoreResult<std::int64_t> put_verdict(const NewVerdict& v);
  // The serial's latest verdict; empty when it has none.
  StoreResult<std::optional<VerdictRecord>> latest_verdict(std::string_view serial);
  // The verdicts a run decided, by unit then id.
  StoreResult<std::vector<VerdictRecord>> run_verdicts(std::int64_t run_id);
  // Every verdict, by id (the plant link's reconciliation: plant/replicate.cpp).
  StoreResult<std::vector<VerdictRecord>> list_verdicts();
  // --- qualification plans and their queue (store_plans.cpp)
  // A queued plan goes to the end of the queue. Adds a plan_events entry of `event_kind` with
  // `event_detail` in the same transaction.
  StoreResult<std::int64_t> create_plan(const NewPlan& p, std::string_view event_kind,
                                        std::string_view event_detail_json);
  // Sets the state, reason and progress; stamps started_at (running) and ended_at (an end
  // state); leaves the queue when not queued.
  StoreResult<void> update_plan(std::int64_t plan_id, std::string_view state, std::string_view reason,
                                std::string_view progress_json);
  StoreResult<PlanRecord> get_plan(std::int64_t plan_id);
  // Plans in the state (every plan when empty), queued ones in queue order, the rest by id.
  StoreResult<std::vector<PlanRecord>> list_plans(std::optional<std::string_view> state = std::nullopt);
  // Rewrites the queue order to `ids` (exactly the queued plans) and takes out `removed` (a
  // queued plan: it ends aborted, "removed from the queue"), with an audit entry, in one
  // transaction.
  StoreResult<void> set_queue(const std::vector<std::int64_t>& ids, std::optional<std::int64_t> removed,
                              std::string_view event_kind, std::string_view event_detail_json);
  StoreResult<std::int64_t> add_plan_event(std::optional<std::int64_t> plan_id, std::string_view kind,
                                           std::string_view detail_json);
  StoreResult<std::vector<PlanEvent>> plan_events(std::optional<std::int64_t> plan_id);
  // --- the plant outbox (issue 14): runs waiting to be replicated to the plant's PostgreSQL,
  // taken in the order queued (store_outbox.cpp, docs/plant.md).
  // Queues the run; a run already waiting keeps its entry (whose id is returned).
  StoreResult<std::int64_t> enqueue_replication(std::int64_t run_id);
  // Queues every completed run never queued (a bench joining a plant sends its history).
  // Returns how many were queued.
  StoreResult<std::int64_t> enqueue_unqueued_completed_runs();
  // The oldest waiting entries, oldest first.
  StoreResult<std::vector<OutboxEntry>> pending_replications(std::int64_t limit);
  StoreResult<void> mark_replicated(std::int64_t entry_id);
  // Counts the attempt and keeps its error; the entry keeps its place at the head.
  StoreResult<void> mark_replication_failed(std::int64_t entry_id, std::string_view error);
  StoreResult<OutboxStatus> outbox_status();

  // Retention (store_prune.cpp): deletes the samples of the runs that ended before
  // options.before, as PruneOptions says; marks each run first, then deletes in chunks of
  // 50,000 rows, each its own transaction (a daemon writing to the same file waits at most one
  // chunk); a prune cut short leaves a run marked with part of its samples, and the next prune
  // finishes it. invalid_argument for a malformed date.
  StoreResult<PruneReport> prune(const PruneOptions& options);

  // SQLite's integrity check and foreign-key check: an empty list when all is well, or the
  // problems found.
  StoreResult<std::vector<std::string>> integrity_check();

  // How long a write waits for another connection's lock (OpenOptions::busy_timeout_ms at
  // first). The daemon sets 0 while the store refuses its writes, so its retries never stall
  // its loop.
  int busy_timeout_ms() const;
  void set_busy_timeout_ms(int ms);

  // Whether this object holds a connection (false once moved from).
  explicit operator bool() const { return db_ != nullptr; }

 private:
  explicit Store(std::unique_ptr<detail::Database> db);
  std::unique_ptr<detail::Database> db_;
};

}  // namespace fogbench::storage
