// The station's write journal: refused writes kept and written again in order (write_journal.hpp).
#include "fogbench/daemon/write_journal.hpp"

#include <algorithm>

#include <spdlog/spdlog.h>

#include "fogbench/storage/store.hpp"

namespace fogbench::daemon {

namespace {
// Enough for the end of many runs; past it the oldest is given up (logged).
constexpr std::size_t kMaxKept = 10000;

std::string what_of(const WriteJournal::Write& w) {
  return "run " + std::to_string(w.run_id) + ": " +
         (w.state ? "state " + std::string(storage::to_string(*w.state))
                  : std::string(storage::to_string(w.kind)) + " event");
}
}  // namespace

WriteJournal::NoBusyWait::NoBusyWait(storage::Store& store) : store_(store), wait_ms_(store.busy_timeout_ms()) {
  store_.set_busy_timeout_ms(0);
}

WriteJournal::NoBusyWait::~NoBusyWait() { store_.set_busy_timeout_ms(wait_ms_); }

bool WriteJournal::may_pass(storage::StoreErrc c) {
  using storage::StoreErrc;
  return c == StoreErrc::disk_full || c == StoreErrc::io || c == StoreErrc::busy || c == StoreErrc::read_only;
}

storage::StoreResult<void> WriteJournal::write(const Write& w) {
  auto r = without_waiting_if_refused([&]() -> storage::StoreResult<void> {
    if (w.state) return store_.set_run_state(w.run_id, *w.state, w.reason, w.t_s);
    auto id = store_.add_event(w.run_id, w.kind, w.detail_json, w.t_s);
    if (!id) return std::unexpected(id.error());
    return {};
  });
  refused_ = !r && may_pass(r.error().code);
  return r;
}

bool WriteJournal::holds(std::int64_t run_id) const {
  return std::any_of(kept_.begin(), kept_.end(), [&](const Write& k) { return k.run_id == run_id; });
}

bool WriteJournal::write_or_keep(Write w) {
  bool first_kept = false;
  // Behind an earlier write of the same run that is still waiting: keep the order.
  if (!holds(w.run_id)) {
    auto ok = write(w);
    if (ok) return false;
    if (!may_pass(ok.error().code)) {
      spdlog::error("{} not stored ({}): {} {}", what_of(w), storage::to_string(ok.error().code), ok.error().message,
                    w.state ? w.reason : w.detail_json);
      return false;
    }
    spdlog::error("{} not stored yet ({}): {}; kept and written again every 10 s", what_of(w),
                  storage::to_string(ok.error().code), ok.error().message);
    first_kept = true;
  }
  if (kept_.size() >= kMaxKept) {
    const Write& old = kept_.front();
    spdlog::error("run {}: giving up an unrecorded {} ({} kept already)", old.run_id, old.state ? "state" : "event",
                  kMaxKept);
    kept_.pop_front();
  }
  kept_.push_back(std::move(w));
  return first_kept;
}

void WriteJournal::flush() {
  while (!kept_.empty()) {
    const Write& w = kept_.front();
    auto ok = write(w);
    if (!ok && may_pass(ok.error().code)) return;  // still no room: the next retry tries again
    if (ok) spdlog::info("run {}: an unrecorded {} is stored now", w.run_id, w.state ? "state" : "event");
    else spdlog::error("run {}: an unrecorded write is given up: {}", w.run_id, ok.error().message);
    kept_.pop_front();
  }
}

nlohmann::json WriteJournal::unrecorded_end(std::int64_t run_id) const {
  nlohmann::json end = nullptr;
  for (const auto& w : kept_)
    if (w.run_id == run_id && w.state && storage::is_terminal(*w.state))
      end = {{"state", std::string(storage::to_string(*w.state))}, {"reason", w.reason}, {"recorded", false}};
  return end;
}

}  // namespace fogbench::daemon
