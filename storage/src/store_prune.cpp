// The Store's retention (issue 28): `fogctl store prune --before DATE` deletes the samples of
// old runs, the bulk of a store, and keeps everything else a run has (docs/storage.md,
// "Retention"). The other rooms: store.cpp (opening, runs), store_samples.cpp, store_outbox.cpp.
#include <sys/stat.h>
#include <sys/statvfs.h>
#include <unistd.h>

#include <cctype>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "fogbench/storage/prune.hpp"
#include "fogbench/storage/runs.hpp"
#include "fogbench/storage/store.hpp"
#include "store_rows.hpp"

namespace fogbench::storage {
namespace {

constexpr std::int64_t kDeleteChunkRows = 50000;

// YYYY-MM-DD or YYYY-MM-DDTHH:MM:SSZ, checked field by field, as the stored times' form
// (YYYY-MM-DDTHH:MM:SS.mmmZ, compared as text). The error names the field that is wrong.
std::expected<std::string, std::string> cutoff(std::string_view s) {
  const auto digits = [&](std::size_t at, std::size_t n) {
    for (std::size_t i = at; i < at + n; ++i)
      if (i >= s.size() || !std::isdigit(static_cast<unsigned char>(s[i]))) return false;
    return true;
  };
  const auto number = [&](std::size_t at, std::size_t n) { return std::stoi(std::string(s.substr(at, n))); };
  const std::string form = " (give YYYY-MM-DD, midnight UTC, or YYYY-MM-DDTHH:MM:SSZ)";
  if (!(s.size() == 10 || s.size() == 20) || !digits(0, 4) || s[4] != '-' || !digits(5, 2) || s[7] != '-' ||
      !digits(8, 2))
    return std::unexpected("'" + std::string(s) + "' is not a date" + form);
  const int month = number(5, 2), day = number(8, 2);
  if (month < 1 || month > 12) return std::unexpected("'" + std::string(s) + "': month " + std::to_string(month) + " is not 1..12");
  if (day < 1 || day > 31) return std::unexpected("'" + std::string(s) + "': day " + std::to_string(day) + " is not 1..31");
  if (s.size() == 10) return std::string(s) + "T00:00:00.000Z";
  if (s[10] != 'T' || !digits(11, 2) || s[13] != ':' || !digits(14, 2) || s[16] != ':' || !digits(17, 2) ||
      s[19] != 'Z')
    return std::unexpected("'" + std::string(s) + "' is not a date and UTC time" + form);
  if (number(11, 2) > 23 || number(14, 2) > 59 || number(17, 2) > 59)
    return std::unexpected("'" + std::string(s) + "': the time of day is not 00:00:00..23:59:59");
  return std::string(s.substr(0, 19)) + ".000Z";
}

}  // namespace

StoreResult<PruneReport> Store::prune(const PruneOptions& options) {
  assert(db_);
  Database& db = *db_;
  auto before = cutoff(options.before);
  if (!before)
    return std::unexpected(db.error(StoreErrc::invalid_argument, "prune: --before " + before.error()));
  const std::string what = "prune the runs that ended before " + *before;
  PruneReport report;
  report.before = *before;
  report.dry_run = options.dry_run;

  // The candidates: ended before the cut-off and not pruned yet, or pruned by a prune cut short
  // (marked, with samples left: finished below whatever the date).
  struct Candidate {
    std::int64_t id = 0;
    std::string state, ended_at;
    std::optional<std::string> pruned_at, sent_at;
    std::int64_t waiting = 0;
  };
  std::vector<Candidate> candidates;
  {
    auto stmt = db.statement(
        "SELECT r.id, r.state, r.ended_at, r.pruned_at, "
        "(SELECT max(sent_at) FROM plant_outbox o WHERE o.run_id = r.id), "
        "(SELECT count(*) FROM plant_outbox o WHERE o.run_id = r.id AND o.sent_at IS NULL) "
        "FROM runs r WHERE (r.pruned_at IS NULL AND r.ended_at IS NOT NULL AND r.ended_at < ?1) "
        "OR (r.pruned_at IS NOT NULL AND EXISTS (SELECT 1 FROM samples s WHERE s.run_id = r.id)) "
        "ORDER BY r.id");
    if (!stmt) return fail(std::move(stmt));
    Query q(db, *stmt);
    q.bind(1, *before);
    int rc;
    while ((rc = q.step()) == SQLITE_ROW)
      candidates.push_back({q.int64(0), q.text(1), q.opt_text(2).value_or(""), q.opt_text(3), q.opt_text(4), q.int64(5)});
    if (rc != SQLITE_DONE) return std::unexpected(db.error(rc, what));
  }

  for (const auto& c : candidates) {
    const bool finishing = c.pruned_at.has_value();
    if (!finishing) {
      std::string reason;
      if (c.state == "interrupted")
        reason = "interrupted: it may still be resumed (abort it to end it)";
      else if (c.state != "completed" && c.state != "aborted" && c.state != "failed")
        reason = "still " + c.state;
      else if (!options.include_unreplicated && c.waiting > 0)
        reason = "waiting in the plant outbox: the plant store has not received it yet";
      else if (!options.include_unreplicated && !c.sent_at)
        reason = "never sent to the plant store (--include-unreplicated deletes its samples for good)";
      if (!reason.empty()) {
        report.kept.push_back({c.id, c.ended_at, std::move(reason)});
        continue;
      }
    }
    PrunedRun p{c.id, c.ended_at, c.state, {}, 0, c.sent_at};
    {
      auto stmt = db.statement("SELECT serial FROM run_units WHERE run_id = ?1 ORDER BY unit_index");
      if (!stmt) return fail(std::move(stmt));
      Query q(db, *stmt);
      q.bind(1, c.id);
      int rc;
      while ((rc = q.step()) == SQLITE_ROW) p.serials.push_back(q.text(0));
      if (rc != SQLITE_DONE) return std::unexpected(db.error(rc, what));
    }
    {
      auto stmt = db.statement("SELECT count(*) FROM samples WHERE run_id = ?1");
      if (!stmt) return fail(std::move(stmt));
      Query q(db, *stmt);
      q.bind(1, c.id);
      auto got = row(db, q, what);
      if (!got) return fail(std::move(got));
      p.samples = q.int64(0);
    }
    if (!options.dry_run) {
      const std::string run_what = "prune " + run_label(c.id);
      if (!finishing) {
        // Marked first, in one transaction with its event: from here the run says it is pruned
        // (its samples are refused by export), whether or not the deletes below all happen.
        Transaction tx(db);
        if (auto ok = tx.begin(run_what); !ok) return fail(std::move(ok));
        auto mark = db.statement("UPDATE runs SET pruned_at = ?2, pruned_samples = ?3 WHERE id = ?1");
        if (!mark) return fail(std::move(mark));
        {
          Query q(db, *mark);
          q.bind(1, c.id).bind(2, db.now_iso()).bind(3, p.samples);
          if (auto ok = run(db, q, run_what); !ok) return fail(std::move(ok));
        }
        nlohmann::json detail = {{"pruned", {{"samples", p.samples}, {"before", *before},
                                             {"plant_sent_at", c.sent_at ? nlohmann::json(*c.sent_at) : nlohmann::json(nullptr)}}}};
        if (auto ok = insert_event(db, c.id, std::nullopt, EventKind::note, detail.dump()); !ok)
          return fail(std::move(ok));
        if (auto ok = tx.commit(run_what); !ok) return fail(std::move(ok));
      }
      auto del = db.statement(
          "DELETE FROM samples WHERE run_id = ?1 AND (unit_index, t_s) IN "
          "(SELECT unit_index, t_s FROM samples WHERE run_id = ?1 LIMIT ?2)");
      if (!del) return fail(std::move(del));
      for (;;) {
        Query q(db, *del);
        q.bind(1, c.id).bind(2, kDeleteChunkRows);
        if (auto ok = run(db, q, run_what); !ok) return fail(std::move(ok));
        if (sqlite3_changes(db.handle()) == 0) break;
      }
    }
    report.samples += p.samples;
    report.pruned.push_back(std::move(p));
  }
  return report;
}

namespace {

std::int64_t file_size_or_0(const std::filesystem::path& p) {
  std::error_code ec;
  const auto n = std::filesystem::file_size(p, ec);
  return ec ? 0 : static_cast<std::int64_t>(n);
}

// SQLite's unix VFS puts its temporary files in the first of these that is a writable folder
// (os_unix.c, unixTempFileDir).
std::filesystem::path sqlite_temp_dir() {
  std::vector<std::string> candidates;
  for (const char* var : {"SQLITE_TMPDIR", "TMPDIR"})
    if (const char* v = std::getenv(var); v && *v) candidates.emplace_back(v);
  for (const char* d : {"/var/tmp", "/usr/tmp", "/tmp"}) candidates.emplace_back(d);
  for (const auto& d : candidates) {
    struct stat st{};
    if (::stat(d.c_str(), &st) == 0 && S_ISDIR(st.st_mode) && ::access(d.c_str(), W_OK | X_OK) == 0) return d;
  }
  return ".";
}

struct FreeSpace {
  std::int64_t bytes = 0;
  unsigned long fsid = 0;
  bool known = false;
};
FreeSpace free_space(const std::filesystem::path& dir) {
  struct statvfs v{};
  if (::statvfs(dir.c_str(), &v) != 0) return {};
  return {static_cast<std::int64_t>(v.f_bavail) * static_cast<std::int64_t>(v.f_frsize), v.f_fsid, true};
}

std::string mb(std::int64_t bytes) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.1f MB", static_cast<double>(bytes) / 1e6);
  return buf;
}

}  // namespace

StoreResult<VacuumReport> Store::vacuum() {
  assert(db_);
  Database& db = *db_;
  const std::filesystem::path path = db.path();
  const std::string what = "vacuum " + path.string();
  if (path == ":memory:") return VacuumReport{};
  VacuumReport report;
  const std::filesystem::path wal = path.string() + "-wal";
  report.bytes_before = file_size_or_0(path) + file_size_or_0(wal);

  std::int64_t page_size = 0, pages = 0, free_pages = 0;
  for (auto [sql, out] : {std::pair<const char*, std::int64_t*>{"PRAGMA page_size", &page_size},
                          {"PRAGMA page_count", &pages},
                          {"PRAGMA freelist_count", &free_pages}}) {
    auto stmt = db.statement(sql);
    if (!stmt) return std::unexpected(stmt.error());
    Query q(db, *stmt);
    auto got = row(db, q, what);
    if (!got) return std::unexpected(got.error());
    *out = q.int64(0);
  }
  report.live_bytes = (pages - free_pages) * page_size;

  // Checked before anything is written: SQLite would stop with SQLITE_FULL part way, after
  // filling the disk the daemon also writes to.
  const auto dir = path.has_parent_path() ? path.parent_path() : std::filesystem::path(".");
  const FreeSpace store_fs = free_space(dir);
  const auto temp_dir = sqlite_temp_dir();
  const FreeSpace temp_fs = free_space(temp_dir);
  report.free_bytes = store_fs.bytes;
  if (store_fs.known && temp_fs.known) {
    const bool one_fs = store_fs.fsid == temp_fs.fsid;
    const std::int64_t need_store = one_fs ? 2 * report.live_bytes : report.live_bytes;
    if (store_fs.bytes < need_store)
      return std::unexpected(db.error(StoreErrc::disk_full,
          what + ": needs " + mb(need_store) + " free in " + dir.string() + " (the " + mb(report.live_bytes) +
              " in use, copied " + (one_fs ? "twice: SQLite's temporary copy in " + temp_dir.string() + " and the WAL" : "once, into the WAL") +
              "), " + mb(store_fs.bytes) + " free; nothing changed"));
    if (!one_fs && temp_fs.bytes < report.live_bytes)
      return std::unexpected(db.error(StoreErrc::disk_full,
          what + ": needs " + mb(report.live_bytes) + " free in SQLite's temporary folder " + temp_dir.string() +
              " (set SQLITE_TMPDIR to a folder with room), " + mb(temp_fs.bytes) + " free; nothing changed"));
  }

  if (auto ok = db.exec("VACUUM", what); !ok) return std::unexpected(ok.error());
  // The rewritten pages are in the WAL until a checkpoint copies them back and truncates both.
  if (auto ok = db.exec("PRAGMA wal_checkpoint(TRUNCATE)", what + ": checkpoint"); !ok) return std::unexpected(ok.error());
  report.bytes_after = file_size_or_0(path) + file_size_or_0(wal);
  return report;
}

}  // namespace fogbench::storage
