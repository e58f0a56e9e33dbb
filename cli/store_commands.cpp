// fogctl store prune and vacuum: retention for the bench's store (issue 28). prune opens the
// store file itself (SQLite lets it share the file with a running fogbenchd: each delete is a
// short transaction), so an admin prunes with the daemon running or stopped; vacuum rewrites
// the file and takes the store's lock first, so it runs only with the daemon stopped.
// docs/storage.md, "Retention".
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "client.hpp"
#include "common.hpp"
#include "fogbench/storage/lock.hpp"
#include "fogbench/storage/prune.hpp"
#include "fogbench/storage/store.hpp"
#include "table.hpp"

namespace fogbench::cli {
namespace {

using nlohmann::json;

struct PruneCliOptions {
  std::string store;
  std::string before;
  bool include_unreplicated = false;
  bool dry_run = false;
  bool json_out = false;
};

std::string join(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& x : v) s += (s.empty() ? "" : ", ") + x;
  return s;
}

int run_store_prune(const PruneCliOptions& o, std::ostream& out, std::ostream& err) {
  // Never create a store by mistyping its path: Store::open would make an empty one.
  std::error_code ec;
  if (o.store != ":memory:" && !std::filesystem::is_regular_file(o.store, ec)) {
    err << "fogctl store prune: --store " << o.store << ": no such store file (fogbenchd's storage.path)\n";
    return kExitError;
  }
  auto store = storage::Store::open(o.store);
  if (!store) {
    err << "fogctl store prune: " << store.error().message << "\n";
    return kExitError;
  }
  storage::PruneOptions po;
  po.before = o.before;
  po.include_unreplicated = o.include_unreplicated;
  po.dry_run = o.dry_run;
  auto r = store->prune(po);
  if (!r) {
    // What was pruned before a failure stays pruned and marked; a second prune finishes it.
    err << "fogctl store prune: " << r.error().message << "\n";
    return kExitError;
  }
  if (o.json_out) {
    json pruned = json::array(), kept = json::array();
    for (const auto& p : r->pruned)
      pruned.push_back({{"run_id", p.run_id}, {"ended_at", p.ended_at}, {"state", p.state}, {"serials", p.serials},
                        {"samples", p.samples}, {"plant_sent_at", p.sent_at ? json(*p.sent_at) : json(nullptr)}});
    for (const auto& k : r->kept)
      kept.push_back({{"run_id", k.run_id}, {"ended_at", k.ended_at}, {"reason", k.reason}});
    out << json{{"store", o.store}, {"before", r->before}, {"dry_run", r->dry_run}, {"pruned", pruned},
                {"kept", kept}, {"samples", r->samples}}
               .dump()
        << "\n";
    return kExitOk;
  }
  const std::string verb = r->dry_run ? "would delete" : "deleted";
  if (r->pruned.empty()) {
    out << "no run that ended before " << r->before << " has samples to prune\n";
  } else {
    // Titled as the kept runs' table below; the samples' header one word, so the table fits 60 columns.
    out << (r->dry_run ? "would prune" : "pruned") << " (ended before " << r->before << "):\n";
    Table t({"run", "ended", "state", "serials", "samples", "plant store received"});
    for (const auto& p : r->pruned)
      t.add({std::to_string(p.run_id), p.ended_at, p.state, join(p.serials), std::to_string(p.samples),
             p.sent_at ? *p.sent_at : "never"});
    out << t.str();
  }
  if (!r->kept.empty()) {
    out << "kept (ended before " << r->before << "):\n";
    Table t({"run", "ended", "why"});
    for (const auto& k : r->kept) t.add({std::to_string(k.run_id), k.ended_at, k.reason});
    out << t.str();
  }
  std::ostringstream summary;
  summary << (r->dry_run ? "dry run: nothing changed; " : "") << r->pruned.size() << " run"
          << (r->pruned.size() == 1 ? "" : "s") << ", " << r->samples << " samples " << verb
          << "; records, events, models, verdicts and certificates kept";
  if (!r->dry_run && !r->pruned.empty())
    summary << ". The file does not shrink: SQLite reuses the freed pages for new runs (`fogctl store vacuum`, with "
               "fogbenchd stopped, gives them back)";
  summary << "\n";
  // A sentence within the terminal's width (the tables above are fitted by Table::str).
  out << fit_lines(summary.str(), output_width());
  return kExitOk;
}

struct VacuumCliOptions {
  std::string store;
  bool json_out = false;
};

std::string megabytes(std::int64_t bytes) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.1f MB", static_cast<double>(bytes) / 1e6);
  return buf;
}

// VACUUM rewrites the whole file: done only while this process holds the store's lock, so no
// fogbenchd records meanwhile (its every write would wait for the rewrite) or starts during it.
int run_store_vacuum(const VacuumCliOptions& o, std::ostream& out, std::ostream& err) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(o.store, ec)) {
    err << "fogctl store vacuum: --store " << o.store << ": no such store file (fogbenchd's storage.path)\n";
    return kExitError;
  }
  auto lock = storage::StoreLock::acquire(o.store);
  if (!lock) {
    err << "fogctl store vacuum: " << lock.error().message
        << (lock.error().held_by_other ? "; stop fogbenchd first (systemctl stop fogbenchd): VACUUM rewrites the whole "
                                         "file and a recording daemon would wait for it"
                                       : "")
        << "\n";
    return kExitError;
  }
  storage::OpenOptions so;
  so.create = false;
  auto store = storage::Store::open(o.store, so);
  if (!store) {
    err << "fogctl store vacuum: " << store.error().message << "\n";
    return kExitError;
  }
  if (!o.json_out) err << "fogctl store vacuum: rewriting " << o.store << " (it holds the store until done)...\n";
  auto r = store->vacuum();
  if (!r) {
    err << "fogctl store vacuum: " << r.error().message << "\n";
    return kExitError;
  }
  if (o.json_out) {
    out << json{{"store", o.store},          {"bytes_before", r->bytes_before}, {"bytes_after", r->bytes_after},
                {"live_bytes", r->live_bytes}, {"free_bytes", r->free_bytes}}
               .dump()
        << "\n";
    return kExitOk;
  }
  out << o.store << ": " << megabytes(r->bytes_before) << " -> " << megabytes(r->bytes_after) << " ("
      << megabytes(std::max<std::int64_t>(0, r->bytes_before - r->bytes_after)) << " given back to the filesystem)\n";
  return kExitOk;
}

}  // namespace

void add_store_commands(CLI::App& app, int& code) {
  auto* s = app.add_subcommand("store", "The bench's store (the SQLite file fogbenchd records in): retention and its space");
  s->require_subcommand(1);
  static PruneCliOptions po;
  auto* p = s->add_subcommand(
      "prune",
      "Delete the samples of runs ended before a date that the plant store has; keep the records");
  p->add_option("--store", po.store, "The store file (fogbenchd's storage.path)")->required();
  p->add_option("--before", po.before, "Runs that ended before this: YYYY-MM-DD (midnight UTC) or YYYY-MM-DDTHH:MM:SSZ")
      ->required();
  p->add_flag("--include-unreplicated", po.include_unreplicated,
              "Also prune runs the plant store has not received (their samples are then gone for good)");
  p->add_flag("--dry-run", po.dry_run, "Say what would be pruned; change nothing");
  p->add_flag("--json", po.json_out, "Print JSON for machines");
  p->callback([&] { code = run_store_prune(po, std::cout, std::cerr); });

  static VacuumCliOptions vo;
  auto* v = s->add_subcommand(
      "vacuum", "Give the space pruned runs freed back to the filesystem (rewrites the file; fogbenchd must be stopped)");
  v->add_option("--store", vo.store, "The store file (fogbenchd's storage.path)")->required();
  v->add_flag("--json", vo.json_out, "Print JSON for machines");
  v->callback([&] { code = run_store_vacuum(vo, std::cout, std::cerr); });
}

}  // namespace fogbench::cli
