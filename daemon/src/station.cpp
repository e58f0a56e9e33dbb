// The run state machine, the per-second samples and the automatic fit or verification.
#include "fogbench/daemon/station.hpp"

#include "fogbench/daemon/analysis.hpp"

#include <algorithm>
#include <cassert>
#include <chrono>
#include <cmath>
#include <ctime>
#include <fstream>
#include <regex>
#include <sstream>

#include <spdlog/spdlog.h>

#include "fogbench/model/json.hpp"
#include "fogbench/model/model.hpp"
#include "fogbench/model/terms.hpp"
#include "fogbench/model/workbench.hpp"

namespace fogbench::daemon {

using nlohmann::json;
using storage::RunState;

std::string iso8601_now() {
  const std::time_t t = std::chrono::system_clock::to_time_t(std::chrono::system_clock::now());
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

namespace {

ApiError from_store(const storage::StoreError& e) {
  if (e.code == storage::StoreErrc::not_found) return {ErrorCode::not_found, e.message};
  return {ErrorCode::internal, std::string(storage::to_string(e.code)) + ": " + e.message};
}

model::Phase to_model_phase(profiles::Phase p) {
  switch (p) {
    case profiles::Phase::settle: return model::Phase::settle;
    case profiles::Phase::hold: return model::Phase::hold;
    case profiles::Phase::heating: return model::Phase::heating;
    case profiles::Phase::cooling: return model::Phase::cooling;
  }
  return model::Phase::unknown;
}

// A JSON number, or null for a value not read (JSON has no NaN).
json num(std::optional<double> v) { return protocol::number_or_null(v); }
double or_nan(std::optional<double> v) { return v ? *v : storage::kNoValue; }

// Readings outside these are implausible for a coil or a gyro on a drift bench.
constexpr double kCoilMinC = -100.0, kCoilMaxC = 200.0;
constexpr double kGyroMaxAbsDph = 1.0e5;
// A setpoint that moved at least this much should have moved the PV (several register steps
// of 0.1 degC): below it a frozen PV cannot be told from a chamber at rest.
constexpr double kSetpointMovedC = 0.5;

bool valid_profile_name(const std::string& name) {
  static const std::regex re("[A-Za-z0-9_][A-Za-z0-9_.-]{0,63}");
  return std::regex_match(name, re);
}

}  // namespace

Station::Station(DaemonConfig config, storage::Store& store, double time_scale, WallClock wall_clock)
    : config_(std::move(config)),
      store_(store),
      time_scale_(time_scale),
      wall_clock_(wall_clock ? std::move(wall_clock) : WallClock(iso8601_now)),
      setpoint_c_(config_.safe_setpoint_c),
      power_(config_.drivers.units.size()) {}

namespace {
// Failures that may pass (room made on the disk, a lock released): worth writing again.
bool may_pass(storage::StoreErrc c) {
  using storage::StoreErrc;
  return c == StoreErrc::disk_full || c == StoreErrc::io || c == StoreErrc::busy || c == StoreErrc::read_only;
}
}  // namespace

template <class Call>
auto Station::without_waiting_if_refused(Call&& call) {
  if (!store_refused_) return call();
  const int wait_ms = store_.busy_timeout_ms();
  store_.set_busy_timeout_ms(0);
  auto r = call();
  store_.set_busy_timeout_ms(wait_ms);
  return r;
}

ApiResult<std::vector<std::int64_t>> Station::recover() {
  recovery_tried_clock_s_ = clock_s_;
  // The first try at start-up waits for a lock like any write; the retries do not.
  auto ids = without_waiting_if_refused(
      [&] { return store_.mark_interrupted_runs("daemon restarted: the run was in progress when it stopped"); });
  store_refused_ = !ids && may_pass(ids.error().code);
  if (!ids) {
    recovery_error_ = std::string(storage::to_string(ids.error().code)) + ": " + ids.error().message;
    return std::unexpected(from_store(ids.error()));
  }
  recovery_error_.reset();
  return *ids;
}

namespace {
ApiError not_recovered(const std::string& why) {
  return {ErrorCode::internal,
          "the runs a crash left in progress are not yet marked interrupted (" + why +
              "); fogbenchd retries every 10 s and starts no run until it has"};
}
}  // namespace

std::optional<std::int64_t> Station::active_run_id() const {
  if (!run_) return std::nullopt;
  return run_->id;
}

std::vector<std::string> Station::profile_names() const {
  std::vector<std::string> names;
  std::error_code ec;
  for (const auto& e : std::filesystem::directory_iterator(config_.profile_dir, ec)) {
    if (e.path().extension() == ".profile") names.push_back(e.path().stem().string());
  }
  std::sort(names.begin(), names.end());
  return names;
}

ApiResult<profiles::Profile> Station::check_profile_text(const std::string& text,
                                                         const std::string& source) const {
  auto p = profiles::parse_profile(text, source);
  if (!p) return api_error(ErrorCode::invalid_profile, p.error().to_string());
  if (auto ok = profiles::check_limits(*p, config_.limits); !ok)
    return api_error(ErrorCode::limits, ok.error().to_string());
  return std::move(*p);
}

ApiResult<profiles::Profile> Station::load_profile(const std::string& name, std::string* text) const {
  if (!valid_profile_name(name))
    return api_error(ErrorCode::bad_request, "profile: expected a name of letters, digits, '_', '-' or '.'");
  const auto path = config_.profile_dir / (name + ".profile");
  std::ifstream in(path);
  if (!in) return api_error(ErrorCode::not_found, "profile " + name + ": not in " + config_.profile_dir.string());
  std::stringstream ss;
  ss << in.rdbuf();
  auto p = check_profile_text(ss.str(), name + ".profile");
  if (p && text) *text = ss.str();
  return p;
}

storage::StoreResult<void> Station::write(const Unrecorded& w) {
  auto r = without_waiting_if_refused([&]() -> storage::StoreResult<void> {
    if (w.state) return store_.set_run_state(w.run_id, *w.state, w.reason, w.t_s);
    auto id = store_.add_event(w.run_id, w.kind, w.detail_json, w.t_s);
    if (!id) return std::unexpected(id.error());
    return {};
  });
  store_refused_ = !r && may_pass(r.error().code);
  return r;
}

namespace {
std::string what_of(const std::string& state_or_kind, std::int64_t run_id) {
  return "run " + std::to_string(run_id) + ": " + state_or_kind;
}
// Enough for the end of many runs; past it the oldest is given up (logged).
constexpr std::size_t kMaxUnrecorded = 10000;
}  // namespace

void Station::write_or_keep(Unrecorded w) {
  const std::string what = what_of(w.state ? "state " + std::string(storage::to_string(*w.state))
                                           : std::string(storage::to_string(w.kind)) + " event",
                                   w.run_id);
  // Behind an earlier write of the same run that is still waiting: keep the order.
  const bool behind = std::any_of(unrecorded_.begin(), unrecorded_.end(),
                                  [&](const Unrecorded& u) { return u.run_id == w.run_id; });
  if (!behind) {
    auto ok = write(w);
    if (ok) return;
    if (!may_pass(ok.error().code)) {
      spdlog::error("{} not stored ({}): {} {}", what, storage::to_string(ok.error().code), ok.error().message,
                    w.state ? w.reason : w.detail_json);
      return;
    }
    spdlog::error("{} not stored yet ({}): {}; kept and written again every 10 s", what,
                  storage::to_string(ok.error().code), ok.error().message);
    unrecorded_tried_clock_s_ = clock_s_;
  }
  if (unrecorded_.size() >= kMaxUnrecorded) {
    const Unrecorded& old = unrecorded_.front();
    spdlog::error("run {}: giving up an unrecorded {} ({} kept already)", old.run_id,
                  old.state ? "state" : "event", kMaxUnrecorded);
    unrecorded_.pop_front();
  }
  unrecorded_.push_back(std::move(w));
}

void Station::flush_unrecorded() {
  while (!unrecorded_.empty()) {
    const Unrecorded& w = unrecorded_.front();
    auto ok = write(w);
    if (!ok && may_pass(ok.error().code)) return;  // still no room: the next tick tries again
    if (ok) spdlog::info("run {}: an unrecorded {} is stored now", w.run_id, w.state ? "state" : "event");
    else spdlog::error("run {}: an unrecorded write is given up: {}", w.run_id, ok.error().message);
    unrecorded_.pop_front();
  }
}

json Station::unrecorded_end(std::int64_t run_id) const {
  json end = nullptr;
  for (const auto& w : unrecorded_)
    if (w.run_id == run_id && w.state && storage::is_terminal(*w.state))
      end = {{"state", std::string(storage::to_string(*w.state))}, {"reason", w.reason}, {"recorded", false}};
  return end;
}

void Station::event(std::int64_t run_id, storage::EventKind kind, const json& detail,
                    std::optional<double> t_s) {
  // An event that cannot be stored is still published and logged, and kept to be written
  // when the store takes it again; the daemon keeps running.
  write_or_keep({run_id, std::nullopt, "", kind, detail.dump(), t_s});
  emit(protocol::to_json(protocol::EventMessage{run_id, t_s, std::string(storage::to_string(kind)), detail}));
}

void Station::audit(std::int64_t run_id, const json& command) {
  std::optional<double> t_s;
  if (run_ && run_->id == run_id) t_s = run_->elapsed_s;
  event(run_id, storage::EventKind::command, command, t_s);
}

void Station::transition(ActiveRun& run, RunState to, const std::string& reason,
                         std::optional<double> t_s) {
  const RunState from = run.state;
  run.state = to;
  write_or_keep({run.id, to, reason, storage::EventKind::state, "", t_s});
  emit(protocol::to_json(protocol::EventMessage{
      run.id, t_s, "state",
      {{"from", std::string(storage::to_string(from))}, {"to", std::string(storage::to_string(to))}, {"reason", reason}}}));
}

// A run started while the chamber cannot be polled would only wait out link_loss.tolerance_s
// and abort: refused at once instead. Before the first poll nothing is known and nothing refused.
std::optional<ApiError> Station::chamber_unavailable() const {
  if (!last_input_ || !last_input_->chamber_link_down) return std::nullopt;
  return ApiError{ErrorCode::unavailable,
                  "the chamber link is down (the chamber cannot be polled): no run starts until it answers again"};
}

ApiResult<std::int64_t> Station::start_run(const std::string& profile_name,
                                           const std::vector<std::string>& serials,
                                           const std::string& purpose_text, const json& command) {
  if (run_) return api_error(ErrorCode::busy, "run " + std::to_string(run_->id) + " is " +
                                                  std::string(storage::to_string(run_->state)));
  if (recovery_error_) return std::unexpected(not_recovered(*recovery_error_));
  if (auto down = chamber_unavailable()) return std::unexpected(*down);
  auto purpose = storage::purpose_from_string(purpose_text);
  if (!purpose) return api_error(ErrorCode::bad_request, "purpose: expected \"fit\" or \"verify\"");
  if (serials.empty()) return api_error(ErrorCode::bad_request, "units: expected at least one serial");

  std::vector<std::size_t> index;
  for (std::size_t i = 0; i < serials.size(); ++i) {
    for (std::size_t j = 0; j < i; ++j)
      if (serials[j] == serials[i]) return api_error(ErrorCode::bad_request, "units: " + serials[i] + " given twice");
    const auto& units = config_.drivers.units;
    auto it = std::find_if(units.begin(), units.end(), [&](const auto& u) { return u.serial == serials[i]; });
    if (it == units.end())
      return api_error(ErrorCode::unknown_serial, "unit " + serials[i] + ": not configured on this bench");
    index.push_back(static_cast<std::size_t>(it - units.begin()));
    if (*purpose == storage::Purpose::verify) {
      auto m = store_.current_model(serials[i]);
      if (!m) return std::unexpected(from_store(m.error()));
      if (!*m) return api_error(ErrorCode::unknown_serial, "unit " + serials[i] + ": no model to verify");
    }
  }

  std::string text;
  auto profile = load_profile(profile_name, &text);
  if (!profile) return std::unexpected(profile.error());

  storage::NewRun nr;
  nr.profile_name = profile_name;
  nr.profile_text = text;
  nr.purpose = *purpose;
  nr.config_json = config_.source.dump();
  nr.time_scale = time_scale_;
  nr.unit_serials = serials;
  auto id = store_.create_run(nr);
  if (!id) return std::unexpected(from_store(id.error()));

  ActiveRun run;
  run.id = *id;
  run.purpose = *purpose;
  run.profile_name = profile_name;
  run.serials = serials;
  run.config_index = std::move(index);
  run.executor = std::make_unique<profiles::Executor>(std::move(*profile));
  run_ = std::move(run);
  event(*id, storage::EventKind::command, command, std::nullopt);
  return *id;
}

ApiResult<std::int64_t> Station::resume_run(std::int64_t run_id, double now_wall_time, const json& command) {
  if (run_) return api_error(ErrorCode::busy, "run " + std::to_string(run_->id) + " is " +
                                                  std::string(storage::to_string(run_->state)));
  if (recovery_error_) return std::unexpected(not_recovered(*recovery_error_));
  if (auto down = chamber_unavailable()) return std::unexpected(*down);
  auto detail = store_.get_run(run_id);
  if (!detail) return std::unexpected(from_store(detail.error()));
  const storage::RunRecord& rec = detail->run;
  if (rec.state != RunState::interrupted)
    return api_error(ErrorCode::bad_request, "run_id: run " + std::to_string(run_id) + " is " +
                                                 std::string(storage::to_string(rec.state)) +
                                                 "; only an interrupted run resumes");
  ActiveRun run;
  run.id = run_id;
  run.purpose = rec.purpose;
  run.profile_name = rec.profile_name;
  for (const auto& u : rec.units) {
    const auto& units = config_.drivers.units;
    auto it = std::find_if(units.begin(), units.end(), [&](const auto& c) { return c.serial == u.serial; });
    if (it == units.end())
      return api_error(ErrorCode::unknown_serial, "unit " + u.serial + ": not configured on this bench");
    run.serials.push_back(u.serial);
    run.config_index.push_back(static_cast<std::size_t>(it - units.begin()));
  }
  auto profile = check_profile_text(rec.profile_text, rec.profile_name + ".profile");
  if (!profile) return std::unexpected(profile.error());
  run.executor = std::make_unique<profiles::Executor>(std::move(*profile));

  // Replay the stored seconds through the executor exactly as tick() fed them, gaps held.
  std::vector<std::vector<storage::SampleRow>> rows(run.serials.size());
  for (std::size_t u = 0; u < rows.size(); ++u) {
    for (std::int64_t off = 0;; off += 10000) {
      auto page = store_.get_samples(run_id, static_cast<int>(u), off, 10000);
      if (!page) return std::unexpected(from_store(page.error()));
      rows[u].insert(rows[u].end(), page->begin(), page->end());
      if (page->size() < 10000) break;
    }
  }
  std::size_t n = rows.empty() ? 0 : rows[0].size();
  for (const auto& r : rows) n = std::min(n, r.size());
  double wall_last = now_wall_time;
  for (std::size_t i = 0; i < n; ++i) {
    const storage::SampleRow& r0 = rows[0][i];
    const double t_s = r0.t_s;
    const bool gap = (r0.flags & model::flag::link_gap) != 0;
    if (gap && config_.link_loss.policy == LinkLossConfig::Policy::hold && run.updated) {
      run.held_s += t_s - run.prev_t_s;
    } else {
      profiles::Readings readings;
      readings.chamber_c = r0.chamber_c;
      for (std::size_t u = 0; u < rows.size(); ++u) readings.coils.push_back({rows[u][i].t1_c, rows[u][i].t2_c});
      run.last = run.executor->update(t_s - run.held_s, readings);
      run.updated = true;
    }
    run.prev_t_s = t_s;
    run.phase = run.last.phase;
    run.step = run.last.step_index;
    if (std::isfinite(r0.wall_time)) wall_last = r0.wall_time;
  }
  if (run.last.finished || run.last.failed)
    return api_error(ErrorCode::bad_request, "run_id: run " + std::to_string(run_id) +
                                                 ": its profile had already ended; nothing to resume");
  const double last_t_s = n == 0 ? -1.0 : rows[0][n - 1].t_s;
  // The time the bench was without the daemon, in run seconds: the run clock counts it.
  const double down_s = std::max(0.0, std::floor((now_wall_time - wall_last) * time_scale_));
  const double gap_from_s = last_t_s + 1.0, gap_to_s = last_t_s + 1.0 + down_s;  // [from, to)
  // The gap's seconds as rows, flagged: every second of the run is in the store, none invented.
  for (double t = gap_from_s; t < gap_to_s; t += 1.0) {
    std::vector<storage::SampleRow> gap_rows;
    for (std::size_t u = 0; u < run.serials.size(); ++u) {
      storage::SampleRow r;
      r.unit_index = static_cast<int>(u);
      r.t_s = t;
      r.setpoint_c = run.last.setpoint_c;
      r.phase = to_model_phase(run.last.phase);
      r.step = static_cast<int>(run.last.step_index);
      r.flags = model::flag::missing | model::flag::link_gap;
      gap_rows.push_back(r);
    }
    if (auto ok = store_.append_samples(run_id, gap_rows); !ok) return std::unexpected(from_store(ok.error()));
  }
  run.held_s += down_s;  // the profile clock stood still through the gap
  // The counts go on from the store: every second stored flagged, the gap's included. The
  // frames lost and corrupt before the crash were only in the dead daemon's memory: they count
  // from here.
  run.quality.assign(run.serials.size(), {});
  for (std::size_t u = 0; u < rows.size(); ++u) {
    for (std::size_t i = 0; i < n; ++i) run.quality[u].samples_flagged += rows[u][i].flags != 0;
    run.quality[u].samples_flagged += static_cast<std::uint64_t>(down_s);
  }
  run.prev_t_s = gap_to_s - 1.0;
  run.resume_at_s = gap_to_s;
  run.state = RunState::interrupted;
  run.link_down = true;  // so the first tick records the link as up again when it is
  run_ = std::move(run);
  event(run_id, storage::EventKind::command, command, gap_from_s);
  event(run_id, storage::EventKind::fault,
        {{"resumed", true}, {"gap_from_s", gap_from_s}, {"gap_s", down_s},
         {"profile_clock_s", run_->prev_t_s - run_->held_s}},
        gap_from_s);
  return run_id;
}

ApiResult<std::int64_t> Station::abort_run(const std::string& reason, const json& command) {
  if (!run_) return api_error(ErrorCode::not_found, "no run is active");
  const auto id = run_->id;
  event(id, storage::EventKind::command, command, run_->elapsed_s);
  finish(RunState::aborted, reason);
  return id;
}

void Station::shutdown(const std::string& reason) {
  if (run_) finish(RunState::aborted, reason);
  setpoint_c_ = config_.safe_setpoint_c;
  // A last try for what the store refused; what it still refuses is lost with the process
  // (each was logged when it was refused).
  if (!unrecorded_.empty()) flush_unrecorded();
  if (!unrecorded_.empty())
    spdlog::error("stopping with {} state changes or events the store did not take (see above)", unrecorded_.size());
}

// A run that fails on what it read (a settle that timed out, a chamber fault) after the loop
// fell behind real time: that is the first thing to know about it, since seconds never read
// make a settle time out and blame the chamber wrongly. An operator's abort, a shutdown or a
// full store are what they say.
std::string Station::behind_real_time(const ActiveRun& run, const std::string& why) const {
  if (run.late_s == 0) return why;
  std::ostringstream o;
  o << "the acquisition fell behind real time (" << run.late_s << " of " << run.elapsed_s + 1
    << " s not read in time: the host is too busy for time scale " << time_scale_ << "); " << why;
  return o.str();
}

void Station::finish(RunState to, const std::string& reason) {
  assert(run_);
  ActiveRun& run = *run_;
  event(run.id, storage::EventKind::note, {{"quality", quality_json(run)}}, run.elapsed_s);
  transition(run, to, reason, run.elapsed_s);
  if (to != RunState::completed) spdlog::warn("run {} {}: {}", run.id, storage::to_string(to), reason);
  last_run_ = {{"run_id", run.id}, {"state", std::string(storage::to_string(to))}, {"reason", reason},
               {"elapsed_s", run.elapsed_s}};
  const auto id = run.id;
  const auto purpose = run.purpose;
  const auto serials = run.serials;
  run_.reset();
  setpoint_c_ = config_.safe_setpoint_c;
  if (to == RunState::completed) analyse(id, purpose, serials);
}

void Station::analyse(std::int64_t run_id, storage::Purpose purpose,
                      const std::vector<std::string>& serials) {
  // The fits or verifications are computed on the offload (fogbenchd's analysis worker, with its
  // own read connection): a long fit must not hold up the next run's seconds or the replies.
  // What they produced is stored here, on the loop, in unit order, each with its note.
  const AnalysisConfig config = config_.analysis;
  const std::string created_at = wall_clock_();
  offload_->submit([this, run_id, purpose, serials, config, created_at](storage::Store& reader) -> Offload::Then {
    auto computed = std::make_shared<std::vector<ApiResult<analysis::Commit>>>();
    for (std::size_t i = 0; i < serials.size(); ++i) {
      const int unit = static_cast<int>(i);
      try {
        computed->push_back(purpose == storage::Purpose::fit
                                ? analysis::fit(reader, config, run_id, unit, "", "", created_at)
                                : analysis::verify(reader, config, run_id, unit, std::nullopt));
      } catch (const std::exception& e) {  // a bug: reported as the unit's failed analysis
        computed->push_back(api_error(ErrorCode::internal, e.what()));
      }
    }
    return [this, run_id, purpose, serials, computed] {
      for (std::size_t i = 0; i < serials.size(); ++i) {
        json detail = {{"analysis", std::string(storage::to_string(purpose))}, {"unit", static_cast<int>(i)},
                       {"serial", serials[i]}};
        ApiResult<json> r = (*computed)[i] ? (*(*computed)[i])(store_) : std::unexpected((*computed)[i].error());
        if (r && purpose == storage::Purpose::fit) {
          detail["model_id"] = (*r)["model_id"];
          detail["n_flagged"] = (*r)["n_flagged"];
        } else if (r) {
          detail["verification_id"] = (*r)["verification_id"];
          detail["pass"] = (*r)["pass"];
        }
        detail["ok"] = r.has_value();
        if (!r) detail["error"] = r.error().message;
        event(run_id, storage::EventKind::note, detail, std::nullopt);
      }
    };
  });
}

TickOutput Station::tick(double clock_s, const TickInput& in) {
  clock_s_ = clock_s;
  last_input_ = in;
  ++ticks_;
  // Both retries every 10 s of wall time: a store held locked makes each try wait out its busy
  // timeout (5 s), which must not hold up every second of the loop.
  if (!unrecorded_.empty() && clock_s - unrecorded_tried_clock_s_ >= 10.0 * time_scale_) {
    unrecorded_tried_clock_s_ = clock_s;
    flush_unrecorded();
  }
  if (recovery_error_ && !run_ && clock_s - recovery_tried_clock_s_ >= 10.0 * time_scale_) {
    if (auto ids = recover(); ids) {
      for (auto id : *ids) spdlog::warn("run {} was in progress when the daemon stopped: marked interrupted", id);
      spdlog::info("the store took the interrupted marks; runs may start");
    }
  }
  // Power-ons and restarts of the gyros, from what they sent this period (anything: a corrupt
  // frame is a gyro that is on).
  std::vector<std::optional<std::uint32_t>> sent(config_.drivers.units.size());
  for (std::size_t i = 0; i < sent.size() && i < in.units.size(); ++i)
    if (in.gyro_read) sent[i] = in.units[i].frames + in.units[i].frames_corrupt;
  const auto power_edges = power_.update(clock_s, sent);
  if (!run_) return {setpoint_c_};
  ActiveRun& run = *run_;

  // A gyro's power-on, restart or power-off is an event of the run (and a unit's power-on
  // not seen is said at the start: its samples then carry no time since power-on).
  auto power_event = [&](std::size_t i, std::string_view what, double t_s) {
    const std::size_t ci = run.config_index[i];
    json detail = {{"gyro_power", what}, {"unit", static_cast<int>(i)}, {"serial", run.serials[i]}};
    if (auto since = power_.since_power_on_s(ci, clock_s)) detail["since_power_on_s"] = *since;
    event(run.id, storage::EventKind::note, detail, t_s);
  };
  if (run.state == RunState::pending) {
    run.start_clock_s = clock_s;
    transition(run, RunState::settling, "run started", 0.0);
    for (std::size_t i = 0; i < run.config_index.size(); ++i) {
      const std::size_t ci = run.config_index[i];
      if (ci < power_edges.size() && power_edges[ci] != PowerWatch::Edge::none) continue;  // said below
      power_event(i, power_.since_power_on_s(ci, clock_s) ? "on" : "power_on_not_seen", 0.0);
    }
  } else if (run.state == RunState::interrupted) {
    // Resumed: the run clock goes on from the gap's end.
    run.start_clock_s = clock_s - *run.resume_at_s;
    transition(run, run.phase == profiles::Phase::settle ? RunState::settling : RunState::running,
               "resumed by operator", *run.resume_at_s);
  }
  run.elapsed_s = clock_s - run.start_clock_s;
  const double t_s = run.elapsed_s;
  if (in.late) ++run.late_s;
  for (std::size_t i = 0; i < run.config_index.size(); ++i) {
    const std::size_t ci = run.config_index[i];
    if (ci < power_edges.size() && power_edges[ci] != PowerWatch::Edge::none) power_event(i, to_string(power_edges[ci]), t_s);
  }

  // Alarms and link faults are recorded on their edges, not every second.
  if (in.chamber_alarm != run.alarm) {
    run.alarm = in.chamber_alarm;
    event(run.id, storage::EventKind::alarm, {{"alarm", in.chamber_alarm}, {"source", "chamber"}}, t_s);
  }
  if (in.chamber_link_down != run.link_down) {
    run.link_down = in.chamber_link_down;
    event(run.id, storage::EventKind::fault,
          {{"chamber_link", in.chamber_link_down ? "down" : "up"}}, t_s);
  }

  // The chamber's faults are judged on what was commanded up to now (setpoint_c_), before
  // this second's profile step.
  std::optional<std::string> abort_reason = chamber_fault(run, in, t_s);

  const bool gap = in.chamber_link_down;
  const bool hold = gap && config_.link_loss.policy == LinkLossConfig::Policy::hold && run.updated;
  // Under `hold` the profile clock stands still through a gap: the chamber cannot be told
  // anything, so the profile resumes where it was rather than jumping ahead.
  if (hold) run.held_s += t_s - run.prev_t_s;
  run.prev_t_s = t_s;
  profiles::ExecutorStatus st = run.last;
  if (!hold) {
    profiles::Readings readings;
    readings.chamber_c = in.chamber_c ? *in.chamber_c : std::nan("");
    for (std::size_t ci : run.config_index) {
      const UnitReading* u = ci < in.units.size() ? &in.units[ci] : nullptr;
      readings.coils.push_back({u && u->t1_c ? *u->t1_c : std::nan(""), u && u->t2_c ? *u->t2_c : std::nan("")});
    }
    st = run.executor->update(t_s - run.held_s, readings);
    run.last = st;
    run.updated = true;
  }

  if (run.state == RunState::settling && st.phase != profiles::Phase::settle && !st.failed)
    transition(run, RunState::running,
               run.phase == profiles::Phase::settle ? "settled" : "profile started", t_s);
  if (!run.phase || *run.phase != st.phase || run.step != st.step_index) {
    run.phase = st.phase;
    run.step = st.step_index;
    event(run.id, storage::EventKind::phase,
          {{"phase", std::string(profiles::to_string(st.phase))}, {"step", st.step_index},
           {"line", st.step_line}},
          t_s);
  }

  std::vector<storage::SampleRow> rows;
  rows.reserve(run.config_index.size());
  for (std::size_t i = 0; i < run.config_index.size(); ++i) {
    const std::size_t ci = run.config_index[i];
    const UnitReading u = ci < in.units.size() ? in.units[ci] : UnitReading{};
    storage::SampleRow r;
    r.unit_index = static_cast<int>(i);
    r.t_s = t_s;
    r.wall_time = in.wall_time;
    // The setpoint recorded is the one commanded for this second: the profile's.
    r.setpoint_c = st.setpoint_c;
    r.chamber_c = or_nan(in.chamber_c);
    r.gyro_dph = or_nan(u.gyro_dph);
    r.frames = u.frames;
    r.t1_c = or_nan(u.t1_c);
    r.t2_c = or_nan(u.t2_c);
    r.phase = to_model_phase(st.phase);
    r.step = static_cast<int>(st.step_index);
    std::uint8_t f = 0;
    if (!u.gyro_dph || !u.t1_c || !u.t2_c || !in.chamber_c) f |= model::flag::missing;
    if (u.frames_lost > 0 || u.frames_corrupt > 0) f |= model::flag::frames_lost;
    bool oor = u.out_of_range;
    for (auto t : {u.t1_c, u.t2_c})
      if (t && (*t < kCoilMinC || *t > kCoilMaxC)) oor = true;
    if (u.gyro_dph && std::abs(*u.gyro_dph) > kGyroMaxAbsDph) oor = true;
    if (oor) f |= model::flag::out_of_range;
    if (in.chamber_link_down) f |= model::flag::link_gap;
    if (run.pv_frozen) f |= model::flag::pv_frozen;
    r.flags = f;
    r.since_power_on_s = or_nan(power_.since_power_on_s(ci, clock_s));
    rows.push_back(r);
    if (run.quality.size() < run.config_index.size()) run.quality.resize(run.config_index.size());
    run.quality[i].frames_lost += u.frames_lost;
    run.quality[i].frames_corrupt += u.frames_corrupt;
    run.quality[i].samples_flagged += f != 0;
  }
  auto stored = store_.append_samples(run.id, rows);
  // The run's end that follows must not wait out the lock again (write_or_keep).
  if (!stored && may_pass(stored.error().code)) store_refused_ = true;

  for (const auto& r : rows) {
    auto finite = [](double v) { return std::isfinite(v) ? std::optional(v) : std::nullopt; };
    protocol::SampleMessage m;
    m.run_id = run.id;
    m.t_s = t_s;
    m.state = std::string(storage::to_string(run.state));
    m.phase = std::string(profiles::to_string(st.phase));
    m.step = st.step_index;
    m.elapsed_s = t_s;
    m.remaining_s = st.remaining_s;
    m.setpoint_c = st.setpoint_c;
    m.chamber_c = in.chamber_c;
    m.unit = r.unit_index;
    m.serial = run.serials[static_cast<std::size_t>(r.unit_index)];
    m.gyro_dph = finite(r.gyro_dph);
    m.frames = r.frames.value_or(0);
    m.t1_c = finite(r.t1_c);
    m.t2_c = finite(r.t2_c);
    m.flags = r.flags;
    m.since_power_on_s = finite(r.since_power_on_s);
    emit(protocol::to_json(m));
  }

  if (stored && abort_reason) {
    finish(RunState::aborted, behind_real_time(run, *abort_reason));
  } else if (!stored) {
    // Samples that cannot be stored make the run worthless: stop it rather than run on blind,
    // and make the chamber safe. A fault of the station, as a chamber's is: `aborted`
    // (`failed` is a profile that could not be run, e.g. a settle that timed out).
    const auto& e = stored.error();
    finish(RunState::aborted, std::string(e.code == storage::StoreErrc::disk_full ? "storage full" : "storage failed") +
                                  " (" + std::string(storage::to_string(e.code)) +
                                  "): samples could not be stored: " + e.message);
  } else if (st.failed) {
    finish(RunState::failed, behind_real_time(run, st.failure_reason));
  } else if (st.finished) {
    finish(RunState::completed, "profile finished");
  } else {
    setpoint_c_ = st.setpoint_c;
  }
  return {setpoint_c_};
}

json Station::live_quality(std::int64_t run_id) const {
  if (!run_ || run_->id != run_id) return nullptr;
  return quality_json(*run_);
}

json Station::quality_json(const ActiveRun& run) {
  json q = json::array();
  for (std::size_t i = 0; i < run.serials.size(); ++i) {
    const ActiveRun::Quality z = i < run.quality.size() ? run.quality[i] : ActiveRun::Quality{};
    q.push_back({{"unit", i}, {"serial", run.serials[i]}, {"frames_lost", z.frames_lost},
                 {"frames_corrupt", z.frames_corrupt}, {"samples_flagged", z.samples_flagged}});
  }
  return q;
}

std::optional<std::string> Station::chamber_fault(ActiveRun& run, const TickInput& in, double t_s) {
  auto fmt = [](double v) {
    std::ostringstream o;
    o << v;
    return o.str();
  };
  // The controller's own alarm: it knows something is wrong with the chamber; a drift run
  // through it measures nothing useful.
  const bool alarm_rose = in.chamber_alarm && !run.alarm_seen;
  run.alarm_seen = in.chamber_alarm;
  if (alarm_rose) return std::string("chamber alarm");

  if (in.chamber_link_down) {
    if (!run.link_down_since_s) run.link_down_since_s = t_s;
    const double gap_s = t_s - *run.link_down_since_s;
    if (config_.link_loss.policy == LinkLossConfig::Policy::safe_abort)
      return std::string("chamber link lost (link_loss.policy safe_abort)");
    if (gap_s > config_.link_loss.tolerance_s)
      return "chamber link lost for " + fmt(gap_s) + " s (link_loss.tolerance_s " +
             fmt(config_.link_loss.tolerance_s) + ")";
    return std::nullopt;
  }
  run.link_down_since_s.reset();
  run.pv_frozen = false;
  if (!in.chamber_c) return std::nullopt;
  const double pv_c = *in.chamber_c;

  // Tracking is judged while running only: a settle waits for the chamber with its own timeout.
  const double err_c = std::abs(pv_c - setpoint_c_);
  if (run.state == RunState::running && err_c > config_.tracking.max_error_c) {
    if (!run.track_error_since_s) run.track_error_since_s = t_s;
    if (t_s - *run.track_error_since_s >= config_.tracking.for_s)
      return "chamber not following its setpoint: |PV - setpoint| " + fmt(err_c) + " degC for " +
             fmt(t_s - *run.track_error_since_s) + " s (tracking.max_error_c " +
             fmt(config_.tracking.max_error_c) + ", tracking.for_s " + fmt(config_.tracking.for_s) + ")";
  } else {
    run.track_error_since_s.reset();
  }

  // A PV that does not change at all while the setpoint moves is a frozen sensor or register,
  // not a slow chamber: a live PV changes in its last digit. A steady hold never trips it.
  if (!run.pv_last_c || pv_c != *run.pv_last_c) {
    run.pv_last_c = pv_c;
    run.pv_same_since_s = t_s;
    run.sp_min_c = run.sp_max_c = setpoint_c_;
  } else {
    run.sp_min_c = std::min(run.sp_min_c, setpoint_c_);
    run.sp_max_c = std::max(run.sp_max_c, setpoint_c_);
    // Unchanged while the setpoint moved this much: a stale value, flagged from here on (and
    // the run ends once it lasts tracking.frozen_s).
    run.pv_frozen = run.sp_max_c - run.sp_min_c >= kSetpointMovedC;
    if (t_s - run.pv_same_since_s >= config_.tracking.frozen_s && run.sp_max_c - run.sp_min_c >= kSetpointMovedC)
      return "chamber process value frozen at " + fmt(pv_c) + " degC for " + fmt(t_s - run.pv_same_since_s) +
             " s while the setpoint moved " + fmt(run.sp_max_c - run.sp_min_c) + " degC (tracking.frozen_s " +
             fmt(config_.tracking.frozen_s) + ")";
  }
  return std::nullopt;
}

json Station::status() const {
  json s;
  s["version"] = FOGBENCH_DAEMON_VERSION;
  s["simulated"] = config_.simulated;
  s["time_scale"] = time_scale_;
  s["clock_s"] = clock_s_;
  s["setpoint_c"] = setpoint_c_;
  s["safe_setpoint_c"] = config_.safe_setpoint_c;
  s["limits"] = {{"min_c", config_.limits.min_c}, {"max_c", config_.limits.max_c},
                 {"max_rate_c_per_min", config_.limits.max_rate_c_per_min}};
  json chamber = {{"chamber_c", nullptr}, {"setpoint_c", nullptr}, {"alarm", false}, {"link", "unknown"}};
  json units = json::array();
  for (std::size_t i = 0; i < config_.drivers.units.size(); ++i) {
    json u = {{"serial", config_.drivers.units[i].serial}, {"gyro_dph", nullptr},
              {"frames", 0}, {"t1_c", nullptr}, {"t2_c", nullptr}};
    if (last_input_ && i < last_input_->units.size()) {
      const auto& r = last_input_->units[i];
      u["gyro_dph"] = num(r.gyro_dph);
      u["frames"] = r.frames;
      u["t1_c"] = num(r.t1_c);
      u["t2_c"] = num(r.t2_c);
    }
    units.push_back(u);
  }
  if (last_input_) {
    chamber = {{"chamber_c", num(last_input_->chamber_c)},
               {"setpoint_c", num(last_input_->chamber_setpoint_c)},
               {"alarm", last_input_->chamber_alarm},
               {"link", last_input_->chamber_link_down ? "down" : "up"}};
  }
  s["chamber"] = chamber;
  s["units"] = units;
  if (run_) {
    const auto& r = *run_;
    s["run"] = {{"id", r.id}, {"state", std::string(storage::to_string(r.state))},
                {"profile", r.profile_name}, {"purpose", std::string(storage::to_string(r.purpose))},
                {"units", r.serials}, {"elapsed_s", r.elapsed_s},
                {"remaining_s", r.executor ? json(r.last.remaining_s) : json(nullptr)},
                {"phase", r.phase ? json(std::string(profiles::to_string(*r.phase))) : json(nullptr)},
                {"step", r.step}, {"profile_held_s", r.held_s}, {"quality", quality_json(r)},
                {"link_gap_s", r.link_down_since_s ? json(r.elapsed_s - *r.link_down_since_s) : json(nullptr)}};
    if (r.state == RunState::pending) s["run"]["remaining_s"] = r.executor->profile().nominal_duration_s();
  } else {
    s["run"] = nullptr;
  }
  s["last_run"] = last_run_;
  s["recovery"] = recovery_error_ ? json{{"pending", true}, {"error", *recovery_error_}} : json(nullptr);
  if (last_run_.is_object()) {
    const auto id = last_run_["run_id"].get<std::int64_t>();
    s["last_run"]["recorded"] = std::none_of(unrecorded_.begin(), unrecorded_.end(),
                                             [id](const Unrecorded& u) { return u.run_id == id; });
  }
  return s;
}

}  // namespace fogbench::daemon
