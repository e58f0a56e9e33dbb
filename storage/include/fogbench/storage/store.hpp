// The SQLite store of a fogbench station: runs, their units, samples and audit events, fitted
// models and verifications: the Store class. Each table's records have their own header
// (runs.hpp, samples.hpp, models.hpp, plans.hpp, outbox.hpp, prune.hpp, identity.hpp, verdict.hpp;
// errors.hpp for StoreResult), which this one only declares: a file includes the headers of the
// records it uses beside this one. Schema, migrations and durability are described in docs/storage.md.
//
// Thread safety: a Store is one SQLite connection opened without SQLite's mutexes; use it
// from one thread at a time (one Store per thread is fine: several Stores, in one or several
// processes, may open the same file; WAL lets readers run beside the one writer, and a
// writer waits up to OpenOptions::busy_timeout_ms for another).
#pragma once

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string_view>
#include <vector>

#include "fogbench/storage/errors.hpp"

namespace fogbench::model {
struct RunData;  // model/run.hpp
}

namespace fogbench::storage {

// The records the Store's calls take and return, each defined in its table's header. A call's
// declaration needs no more than their names; a caller that makes or reads one includes its header.
enum class RunState;  // runs.hpp
enum class EventKind;
struct NewRun;
struct RunRecord;
struct RunDetail;
struct RunFilter;
struct SampleRow;  // samples.hpp
struct ExportOptions;
struct ImportOptions;
struct NewModel;  // models.hpp
struct ModelRef;
struct ModelRecord;
struct NewVerification;
struct VerificationRecord;
struct RunIdentity;  // identity.hpp
struct NewCertificate;
struct CertificateRecord;
struct NewVerdict;  // verdict.hpp
struct VerdictRecord;
struct NewPlan;  // plans.hpp
struct PlanRecord;
struct PlanEvent;
struct OutboxEntry;  // outbox.hpp
struct OutboxStatus;
struct PruneOptions;  // prune.hpp
struct PruneReport;
struct VacuumReport;

namespace detail {
class Database;  // the connection and its statement cache (storage/src/sqlite.hpp)
}

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
  StoreResult<std::vector<RunRecord>> list_runs(const RunFilter& filter);
  StoreResult<std::vector<RunRecord>> list_runs();  // every run: a default RunFilter
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
  StoreResult<model::RunData> export_run(std::int64_t run_id, int unit_index, const ExportOptions& options);
  StoreResult<model::RunData> export_run(std::int64_t run_id, int unit_index);  // default ExportOptions
  // Stores a run from a CSV (or any RunData) as a completed run with one unit (index 0), in one
  // transaction. Returns the new run's id.
  StoreResult<std::int64_t> import_run(const model::RunData& data, const ImportOptions& options);

  // --- models and verifications
  // Stores a model as the next version for its serial.
  StoreResult<ModelRef> put_model(const NewModel& m);
  StoreResult<ModelRecord> get_model(std::int64_t model_id);
  // The serial's highest version of the axis' models; empty when it has none. Axis "x" (the
  // default) is also a one-axis unit's model (stored without an axis); "y", "z" a three-axis
  // unit's other axes. Another axis name is invalid_argument.
  StoreResult<std::optional<ModelRecord>> current_model(std::string_view serial, std::string_view axis = "x");
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
  // Gives the pages freed by prune back to the filesystem: SQLite's VACUUM, which copies the
  // pages in use to a temporary database and back through the WAL (the file keeps its inode,
  // owner and mode; a crash leaves it as it was). The caller holds the store's lock (lock.hpp):
  // a daemon writing meanwhile would wait for the whole rewrite. disk_full, naming the sizes,
  // when the store's filesystem or SQLite's temporary folder has less free space than the pages
  // in use (twice that when they are one filesystem), before anything is written.
  StoreResult<VacuumReport> vacuum();

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
