// The plant store (issue 14): every bench's completed runs in one PostgreSQL, schema with
// migrations, replication of a run from a bench's SQLite store (docs/plant.md).
//
// A Connection is one libpq connection; use it from one thread at a time. Every failure is a
// returned PlantError naming what was being done and PostgreSQL's own message.
#pragma once

#include <cstdint>
#include <expected>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace fogbench::storage {
class Store;
}

namespace fogbench::plant {

enum class PlantErrc {
  connect_failed,    // the server refused the login or cannot be reached
  connection_lost,   // the server went away during a call: nothing of the call was committed
  schema_too_new,    // written by a newer fogbench: refused, never modified
  schema_missing,    // a reader found no fogbench plant schema (a bench has never sent a run)
  migration_failed,  // a migration failed; the plant keeps its old version
  invalid_argument,  // a caller's value is unusable (an empty bench id, a lot id too long)
  bench_store,       // the bench's SQLite store failed while its run was read
  sql,               // any other PostgreSQL failure
};
std::string_view to_string(PlantErrc code);

struct PlantError {
  PlantErrc code = PlantErrc::sql;
  std::string message;
};

template <class T>
using PlantResult = std::expected<T, PlantError>;

namespace detail {
struct Conn;
}

// One query's rows as text (NULL: empty optional).
struct Rows {
  std::vector<std::string> columns;
  std::vector<std::vector<std::optional<std::string>>> rows;
};

class Connection {
 public:
  // Connects (conninfo: a libpq connection string or URI, e.g. "host=/tmp port=5433
  // dbname=plant" or "service=plant"). With `migrate` the schema is created or brought up to
  // date (the bench side); without, a missing or older schema is refused (the readers). A
  // schema newer than this fogbench knows is refused either way, untouched.
  // `connect_timeout_s` (> 0) bounds the connection attempt (libpq's connect_timeout: each
  // address's TCP connect and start-up exchange; a name lookup is not bounded by it) unless the
  // conninfo sets its own connect_timeout; it overrides a service file's. 0: libpq's default
  // (no bound: an unreachable host waits for the kernel's retries, about two minutes).
  static PlantResult<Connection> open(const std::string& conninfo, bool migrate, int connect_timeout_s = 0);

  Connection(Connection&&) noexcept;
  Connection& operator=(Connection&&) noexcept;
  ~Connection();

  int schema_version() const { return version_; }
  static int current_schema_version();

  // Runs SQL returning no rows, or rows as text; $1.. take `params` (never spliced in the text).
  PlantResult<void> exec(const std::string& sql, std::string_view what);
  PlantResult<Rows> query(const std::string& sql, const std::vector<std::optional<std::string>>& params,
                          std::string_view what);

  // COPY FROM STDIN of text-format lines (copy_escape for text fields), sent in chunks.
  PlantResult<std::int64_t> copy_in(const std::string& copy_sql, std::string_view data, std::string_view what);
  // The same streamed: copy_begin, copy_put any number of times (text lines or binary-format
  // data, as the COPY statement says), copy_end (the rows the server took). A failure in
  // copy_put leaves the transaction failed: the caller rolls back.
  PlantResult<void> copy_begin(const std::string& copy_sql, std::string_view what);
  PlantResult<void> copy_put(std::string_view data, std::string_view what);
  PlantResult<std::int64_t> copy_end(std::string_view what);

  // Called on the calling thread each time the server answers a statement or takes a chunk
  // (1 MB) of COPY data: how a watcher tells a slow transaction from one that makes no progress.
  void on_progress(std::function<void()> f) { progress_ = std::move(f); }

  // The connection's socket, for a caller that must abandon a call blocked in another thread:
  // shutdown(2) on a dup(2) of it makes the blocked call fail at once with connection_lost (the
  // server rolls the transaction back when it sees the connection gone). libpq's own cancel
  // (PQcancel) asks the server's postmaster to interrupt the backend, which a backend that is
  // stopped or unreachable never acts on; the socket's end does not depend on the server.
  int socket() const;

  detail::Conn& raw() { return *conn_; }

 private:
  explicit Connection(std::unique_ptr<detail::Conn> c);
  void progressed() {
    if (progress_) progress_();
  }
  std::unique_ptr<detail::Conn> conn_;
  int version_ = 0;
  std::function<void()> progress_;
};

// A COPY text field: backslash, tab, newline and carriage return escaped.
void copy_escape(std::string& out, std::string_view field);

struct ReplicateStats {
  std::int64_t units = 0, samples = 0, events = 0, models = 0, verifications = 0, figures = 0;
  std::int64_t verdicts = 0;  // the verdicts the run decided (issue 24)
  // Identity rows written: the run's (run_identity, 0 or 1) plus one per unit (unit_identity).
  std::int64_t identity_rows = 0;
  // The run's serials' certificates: newly stored in the plant, and sent but already held there
  // (immutable: left as they are).
  std::int64_t certificates = 0, certificates_held = 0;
  // Station public keys new to the plant (station_keys), and ones refused: a certificate whose
  // embedded public key is not the key its key_id names.
  std::int64_t station_keys = 0, station_keys_refused = 0;
};

// Replicates one run of the bench's store to the plant in ONE transaction: what the plant held
// for (bench_id, run_id) is replaced (sending twice is harmless), and a failure anywhere (the
// server gone mid-COPY) commits nothing. Sends the run, its identity (when it has one), its units
// (serial, lot), samples (COPY, with the compensated rate), events, the models fitted on it, its
// verifications and their figures, and the certificates of its units' serials (each once: a
// certificate the plant holds is left as it is).
PlantResult<ReplicateStats> replicate_run(Connection& plant, storage::Store& bench, std::string_view bench_id,
                                          std::int64_t run_id);

// Sends the bench's outbox in order, at most `limit` entries: each run replicated, then marked
// sent in the bench's store. Stops at the first failure, which is noted on its entry (attempts,
// last_error; the entry keeps its place at the head) and returned. Returns how many were sent.
// A run replicated but not marked (the bench's store failed just then) is sent again later,
// which is harmless.
PlantResult<std::int64_t> send_outbox(Connection& plant, storage::Store& bench, std::string_view bench_id,
                                      std::int64_t limit);

// The verdicts of this bench that the plant lacks although it holds their runs (runs replicated
// before the plant's schema had verdicts, schema version 4), inserted in one transaction; a
// verdict the plant holds is left as it is. Returns how many were sent. The plant link calls
// it on each new connection: a few ids per run read, nothing sent when nothing is missing.
PlantResult<std::int64_t> send_missing_verdicts(Connection& plant, storage::Store& bench, std::string_view bench_id);

// A bench id or lot id: 1..64 characters, none a control character. "" when fine, else why.
std::string check_id(std::string_view value, std::string_view field);

}  // namespace fogbench::plant
