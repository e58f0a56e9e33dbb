// The qualification-plan runner (plan_runner.hpp, docs/plans.md): checks, the step machine run
// after each tick and the judgement of measurements against limits (the queue: plan_queue.cpp).
// What a limit measures on a run (the Allan figures, the scale factor's, the peak excursion)
// is computed in plan_figures.cpp; this file decides with them.
#include "fogbench/daemon/plan_runner.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>

#include "fogbench/model/firmware.hpp"
#include "fogbench/model/json.hpp"
#include "fogbench/model/model.hpp"
#include "fogbench/profiles/profile.hpp"
#include "fogbench/storage/models.hpp"
#include "fogbench/storage/plans.hpp"
#include "plan_figures.hpp"
#include "verdict.hpp"

namespace fogbench::daemon {

using nlohmann::json;

namespace {

// Where an error of the plan points: "source:line: ".
std::string at_line(const plans::Plan& p, int line) { return p.source + ":" + std::to_string(line) + ": "; }

storage::Purpose run_purpose(plans::StepPurpose p) {
  // soak and custom steps are recorded as fit runs without the automatic fit (docs/plans.md):
  // a fit run needs no model on file.
  return p == plans::StepPurpose::verify ? storage::Purpose::verify : storage::Purpose::fit;
}
bool analysed(plans::StepPurpose p) { return p == plans::StepPurpose::fit || p == plans::StepPurpose::verify; }

json limit_json(const plans::Limit& l) {
  return {{"measurement", l.name()}, {"limit", l.describe()}, {"on_fail", std::string(plans::to_string(l.on_fail))},
          {"line", l.line}};
}

json* find_unit(json& progress, const std::string& serial) {
  for (auto& u : progress["units"])
    if (u["serial"] == serial) return &u;
  return nullptr;
}

// Whether a profile text has rate steps (a run's profile as stored, or a plan step's file).
bool has_rate_steps(const std::string& text, const std::string& name) {
  auto p = profiles::parse_profile(text, name);
  return p && !p->rate_steps.empty();
}

}  // namespace

const std::vector<drivers::UnitConfig>& PlanRunner::bench_slots() const { return runs_.bench_units(); }

namespace {

// The run units of a plan's step: each serial in its slot (`slots`), else in the slot whose
// configured default serial it is.
ApiResult<std::vector<SlotUnit>> plan_slot_units(const std::vector<drivers::UnitConfig>& configured,
                                                 const std::vector<std::string>& units,
                                                 const std::map<std::string, std::string>& slots) {
  std::vector<SlotUnit> out;
  for (const auto& serial : units) {
    auto s = slots.find(serial);
    const auto ci = find_slot(configured, serial,
                              s != slots.end() ? std::optional<std::string_view>(s->second) : std::nullopt);
    if (!ci)
      return api_error(ErrorCode::unknown_serial, s != slots.end()
                                                      ? "units: " + serial + ": slot " + s->second + " is not configured on this bench"
                                                      : "units: " + serial + " is not configured on this bench");
    out.push_back({*ci, serial});
  }
  return out;
}

}  // namespace

ApiResult<plans::Plan> PlanRunner::check(const std::string& text, const std::string& source,
                                         const std::vector<std::string>& units,
                                         const std::map<std::string, std::string>& slots) const {
  auto p = plans::parse_plan(text, source);
  if (!p) return api_error(ErrorCode::bad_request, p.error().to_string());
  for (std::size_t i = 0; i < units.size(); ++i) {
    for (std::size_t j = 0; j < i; ++j)
      if (units[j] == units[i]) return api_error(ErrorCode::bad_request, "units: " + units[i] + " given twice");
  }
  if (auto placed = plan_slot_units(bench_slots(), units, slots); !placed) return std::unexpected(placed.error());
  bool fitted = false;
  bool rate_step_measured = false;  // a fit or verify step whose profile has rate steps
  for (const plans::Step& s : p->steps) {
    auto prof = runs_.load_profile(s.profile);
    if (!prof) return api_error(prof.error().code, at_line(*p, s.line) + "step " + s.profile + ": " + prof.error().message);
    if (!prof->rate_steps.empty() && (s.purpose == plans::StepPurpose::fit || s.purpose == plans::StepPurpose::verify))
      rate_step_measured = true;
    if (s.purpose == plans::StepPurpose::fit) fitted = true;
    if (s.purpose == plans::StepPurpose::verify && !fitted) {
      for (const auto& serial : units) {
        auto m = store_.current_model(serial);
        if (!m) return std::unexpected(from_store(m.error()));
        if (!*m)
          return api_error(ErrorCode::unknown_serial, at_line(*p, s.line) + "step " + s.profile +
                                                          " verify: unit " + serial +
                                                          " has no model on file and no fit step comes before it");
      }
    }
  }
  // The scale factor's measurements need a rate sequence: a limit on one with no fit or verify
  // step whose profile has rate steps would never be measured.
  for (const plans::Limit& l : p->limits)
    if (plans::needs_rate_steps(l.measurement) && !rate_step_measured)
      return api_error(ErrorCode::bad_request,
                       at_line(*p, l.line) + "limit " + l.describe() +
                           ": no fit or verify step of this plan has a profile with rate steps "
                           "(`rate <r> dps for <d>`), so the scale factor is never measured");
  return std::move(*p);
}

ApiResult<json> PlanRunner::validate(const std::string& text, const std::string& source,
                                     const std::vector<std::string>& units,
                                     const std::map<std::string, std::string>& slots) const {
  auto p = check(text, source, units, slots);
  if (!p) return std::unexpected(p.error());
  double nominal_s = 0.0;
  json steps = json::array(), limits = json::array();
  for (const auto& s : p->steps) {
    auto prof = runs_.load_profile(s.profile);
    const double d = prof ? prof->nominal_duration_s() : 0.0;
    nominal_s += d;
    steps.push_back({{"profile", s.profile}, {"purpose", std::string(plans::to_string(s.purpose))}, {"line", s.line},
                     {"nominal_duration_s", d}});
  }
  for (const auto& l : p->limits) limits.push_back(limit_json(l));
  return json{{"valid", true}, {"name", p->name}, {"steps", steps}, {"limits", limits}, {"nominal_duration_s", nominal_s}};
}

std::optional<std::string> PlanRunner::slot_change_refusal(const std::vector<drivers::UnitConfig>& next) const {
  const auto& now = bench_slots();
  for (const char* state : {"running", "queued"}) {
    auto plans = store_.list_plans(state);
    if (!plans) continue;  // the store's error is the next step's to report
    for (const auto& rec : *plans)
      for (const auto& serial : rec.units) {
        auto s = rec.slots.find(serial);
        const auto given = s != rec.slots.end() ? std::optional<std::string_view>(s->second) : std::nullopt;
        const auto before = find_slot(now, serial, given);
        if (!before) continue;  // placed nowhere already: its step's start says so
        const auto after = find_slot(next, serial, given);
        if (after == before) continue;
        return "drivers.units: " + std::string(state) + " plan " + std::to_string(rec.id) + " (" + rec.name +
               ") has " + serial + " in slot " + now[*before].slot + " (position " + std::to_string(*before + 1) +
               "); this file would place it " +
               (after ? "in slot " + next[*after].slot + " (position " + std::to_string(*after + 1) + ")"
                      : std::string("in no slot")) +
               " at the plan's next step: change that slot once the plan has ended, or abort the plan "
               "(fogctl plan abort) or remove it from the queue (fogctl queue remove)";
      }
  }
  return std::nullopt;
}

std::optional<std::int64_t> PlanRunner::running_plan_id() const {
  auto r = store_.list_plans("running");
  if (!r || r->empty()) return std::nullopt;
  return r->front().id;
}

void PlanRunner::plan_event(std::optional<std::int64_t> plan_id, const std::string& kind, const json& detail) {
  if (auto ok = store_.add_plan_event(plan_id, kind, detail.dump()); !ok)
    spdlog::error("plan {}: could not store the event {}: {}", plan_id.value_or(0), kind, ok.error().message);
}

void PlanRunner::save(std::int64_t plan_id, const std::string& state, const std::string& reason, const json& progress) {
  if (auto ok = store_.update_plan(plan_id, state, reason, progress.dump()); !ok)
    spdlog::error("plan {}: could not store its progress: {}", plan_id, ok.error().message);
}

namespace {
json initial_progress(const plans::Plan& p, const std::vector<std::string>& units) {
  json us = json::array();
  for (const auto& s : units)
    us.push_back({{"serial", s}, {"active", true}, {"verdict", nullptr}, {"marginal", false},
                  {"measurements", json::array()}, {"reasons", json::array()}});
  return json{{"step", 0}, {"steps", p.steps.size()}, {"attempt", 0}, {"run_id", nullptr}, {"waiting", "start"},
              {"step_units", nullptr}, {"runs", json::array()}, {"units", us}};
}
}  // namespace

ApiResult<json> PlanRunner::start(const std::string& text, const std::string& source,
                                  const std::vector<std::string>& units, const PlanTrace& trace, const json& command) {
  if (units.empty()) return api_error(ErrorCode::bad_request, "units: expected at least one serial");
  auto p = check(text, source, units, trace.slots);
  if (!p) return std::unexpected(p.error());
  if (auto running = running_plan_id())
    return api_error(ErrorCode::busy, "plan " + std::to_string(*running) + " is running: queue this one (queue.add)");
  if (auto run = runs_.active_run_id())
    return api_error(ErrorCode::busy, "run " + std::to_string(*run) + " is active: queue the plan (queue.add)");
  storage::NewPlan np{p->name, source, text, units, "running", trace.op.name, trace.op.source, trace.lots, trace.slots};
  json detail = command;
  detail.update(plan_trace_json(trace.op.name, trace.op.source, trace.lots));
  auto id = store_.create_plan(np, "plan.start", detail.dump());
  if (!id) return std::unexpected(from_store(id.error()));
  save(*id, "running", "", initial_progress(*p, units));
  json j = {{"plan_id", *id}, {"name", p->name}, {"state", "running"}, {"steps", p->steps.size()}};
  j.update(plan_trace_json(trace.op.name, trace.op.source, trace.lots));
  return j;
}

ApiResult<json> PlanRunner::status(std::optional<std::int64_t> plan_id) const {
  auto& store = store_;
  storage::PlanRecord rec;
  if (plan_id) {
    auto r = store.get_plan(*plan_id);
    if (!r) return std::unexpected(from_store(r.error()));
    rec = std::move(*r);
  } else {
    auto all = store.list_plans();
    if (!all) return std::unexpected(from_store(all.error()));
    const storage::PlanRecord* pick = nullptr;
    for (const auto& r : *all)
      if (r.state == "running") pick = &r;
    if (!pick)  // the last one that ran: a queued plan removed before it started (aborted, never
                // started) did not, and the panel's plan view would show it in place of the last
      for (const auto& r : *all)
        if (r.state != "queued" && r.started_at && (!pick || r.id > pick->id)) pick = &r;
    if (!pick) return api_error(ErrorCode::not_found, "no plan has run yet");
    rec = *pick;
  }
  json progress = json::parse(rec.progress_json, nullptr, false);
  json j = {{"plan_id", rec.id}, {"name", rec.name}, {"source", rec.source}, {"state", rec.state}, {"reason", rec.reason},
            {"units", rec.units}, {"created_at", rec.created_at},
            {"started_at", rec.started_at ? json(*rec.started_at) : json(nullptr)},
            {"ended_at", rec.ended_at ? json(*rec.ended_at) : json(nullptr)}, {"progress", progress},
            {"plan_text", rec.plan_text}};
  j.update(plan_trace_json(rec.operator_name, rec.operator_source, rec.lots));
  j["slots"] = rec.slots;
  if (auto p = plans::parse_plan(rec.plan_text, rec.source)) {
    json steps = json::array();
    for (const auto& s : p->steps)
      steps.push_back({{"profile", s.profile}, {"purpose", std::string(plans::to_string(s.purpose))}, {"line", s.line}});
    j["steps"] = steps;
  }
  if (rec.state == "running") {
    if (auto run = runs_.active_run_id(); run && progress.value("run_id", json()) == *run) {
      auto st = runs_.status();
      j["run"] = st.contains("run") ? st["run"] : json(nullptr);
    }
  }
  return j;
}

ApiResult<json> PlanRunner::abort(const std::string& reason, const json& command) {
  auto id = running_plan_id();
  if (!id) return api_error(ErrorCode::not_found, "no plan is running");
  auto rec = store_.get_plan(*id);
  if (!rec) return std::unexpected(from_store(rec.error()));
  json progress = json::parse(rec->progress_json, nullptr, false);
  const std::string why = "aborted by operator" + (reason.empty() ? std::string() : ": " + reason);
  plan_event(*id, "plan.abort", command);
  if (auto run = runs_.active_run_id(); run && progress.value("run_id", json()) == *run)
    (void)runs_.abort_run(why + " (plan " + std::to_string(*id) + ")", command);
  finish_plan(*id, progress, "aborted", why);
  return json{{"plan_id", *id}, {"state", "aborted"}};
}

void PlanRunner::decide_unit(std::int64_t plan_id, json& progress, json& unit) {
  if (unit.value("decided", false)) return;
  unit["decided"] = true;
  auto& store = store_;
  auto rec = store.get_plan(plan_id);
  if (!rec) {
    spdlog::error("plan {}: cannot read it to store the verdict of {}: {}", plan_id, unit.value("serial", ""),
                  rec.error().message);
    return;
  }
  const std::string serial = unit.value("serial", "");
  std::optional<std::int64_t> model_id;
  if (auto m = store.current_model(serial); m && *m) model_id = (*m)->id;
  // A three-axis unit's axes each name their own current model in the verdict's evidence.
  std::map<std::string, std::int64_t> axis_models;
  if (unit.contains("axis_evidence"))
    for (const char* axis : {"x", "y", "z"})
      if (auto m = store.current_model(serial, axis); m && *m) axis_models[axis] = (*m)->id;
  auto v = verdict::from_plan(plan_id, rec->name, rec->plan_text, unit, progress["runs"], model_id, axis_models);
  if (!v) return;  // the unit never ran: the plan's status says incomplete, nothing to certify
  auto cert = runs_.decide(*v, true);  // the run again to the plant, with its verdict
  if (cert) unit["certificate_sha256"] = *cert;
  else if (cert.error().code != ErrorCode::not_found)  // not_found: no model, so no certificate
    spdlog::error("plan {}: the verdict of {} ({}): {}", plan_id, serial, v->verdict, cert.error().message);
}

void PlanRunner::finish_plan(std::int64_t plan_id, json& progress, const std::string& state, const std::string& reason) {
  for (auto& u : progress["units"]) {
    if (u["verdict"].is_null()) {
      if (state == "completed") u["verdict"] = u["marginal"].get<bool>() ? "marginal" : "pass";
      else u["verdict"] = "incomplete";
    }
    decide_unit(plan_id, progress, u);
  }
  progress["waiting"] = nullptr;
  save(plan_id, state, reason, progress);
  json verdicts = json::object();
  for (const auto& u : progress["units"]) verdicts[u["serial"].get<std::string>()] = u["verdict"];
  plan_event(plan_id, "plan.end", {{"state", state}, {"reason", reason}, {"verdicts", verdicts}});
  spdlog::info("plan {} {}{}", plan_id, state, reason.empty() ? "" : ": " + reason);
}

void PlanRunner::after_tick(double clock_s, double wall_time) {
  auto id = running_plan_id();
  if (id) {
    // A pass may start a run or judge one; a few passes per tick at most.
    for (int i = 0; i < 4 && advance(*id, wall_time); ++i) {
    }
    return;
  }
  // The queue: the next plan starts when the chamber is free (no run active), looked at once
  // per daemon second at most.
  if (clock_s - last_queue_look_s_ < 1.0 || runs_.active_run_id()) return;
  last_queue_look_s_ = clock_s;
  auto queued = store_.list_plans("queued");
  if (!queued || queued->empty()) return;
  const auto& next = queued->front();
  auto p = check(next.plan_text, next.source, next.units, next.slots);
  if (!p) {
    json progress = json::object();
    save(next.id, "failed", "not started: " + p.error().message, progress);
    plan_event(next.id, "plan.end", {{"state", "failed"}, {"reason", p.error().message}});
    return;
  }
  save(next.id, "running", "", initial_progress(*p, next.units));
  json from_queue = {{"from", "queue"}};
  from_queue.update(plan_trace_json(next.operator_name, next.operator_source, next.lots));
  plan_event(next.id, "plan.start", from_queue);
  spdlog::info("plan {} ({}) starts from the queue", next.id, next.name);
}

bool PlanRunner::advance(std::int64_t plan_id, double wall_time) {
  auto rec = store_.get_plan(plan_id);
  if (!rec) return false;
  auto plan = plans::parse_plan(rec->plan_text, rec->source);
  json progress = json::parse(rec->progress_json, nullptr, false);
  if (!plan || progress.is_discarded() || !progress.contains("step")) {
    json p = progress.is_discarded() ? json::object() : progress;
    finish_plan(plan_id, p, "failed", "its stored text or progress does not read back");
    return false;
  }
  const auto step_index = progress["step"].get<std::size_t>();
  if (step_index >= plan->steps.size()) {
    finish_plan(plan_id, progress, "completed", "");
    return false;
  }
  const plans::Step& step = plan->steps[step_index];

  if (progress["run_id"].is_null()) {
    if (runs_.active_run_id()) return false;  // someone else's run: wait for the chamber
    std::vector<std::string> units;
    if (progress["step_units"].is_array()) {
      for (const auto& s : progress["step_units"]) units.push_back(s.get<std::string>());
    } else {
      for (const auto& u : progress["units"])
        if (u["active"].get<bool>()) units.push_back(u["serial"].get<std::string>());
    }
    if (units.empty()) {
      finish_plan(plan_id, progress, "completed", "every unit was dropped before step " + std::to_string(step_index + 1));
      return false;
    }
    // The plan's operator and its units' lots go to the run (its identity and its units).
    json lots = json::object();
    for (const auto& s : units)
      if (auto l = rec->lots.find(s); l != rec->lots.end()) lots[s] = l->second;
    json command = {{"cmd", "plan.step"}, {"plan_id", plan_id}, {"step", step_index + 1}, {"line", step.line},
                    {"attempt", progress["attempt"]}, {"operator", rec->operator_name}, {"lots", lots}};
    auto placed = plan_slot_units(bench_slots(), units, rec->slots);
    if (!placed) {
      finish_plan(plan_id, progress, "failed",
                  at_line(*plan, step.line) + "step " + step.profile + " could not start: " + placed.error().message);
      return false;
    }
    auto run = runs_.start_run_in_slots(step.profile, *placed, run_purpose(step.purpose), command,
                                  OperatorId{rec->operator_name, rec->operator_source});
    if (!run) {
      if (run.error().code == ErrorCode::unavailable || run.error().code == ErrorCode::busy) return false;  // try again
      finish_plan(plan_id, progress, "failed",
                  at_line(*plan, step.line) + "step " + step.profile + " could not start: " + run.error().message);
      return false;
    }
    if (!analysed(step.purpose)) runs_.skip_analysis(*run);
    progress["run_id"] = *run;
    progress["step_units"] = units;
    progress["waiting"] = "run";
    progress["runs"].push_back({{"step", step_index + 1}, {"profile", step.profile},
                                {"purpose", std::string(plans::to_string(step.purpose))}, {"attempt", progress["attempt"]},
                                {"run_id", *run}, {"units", units}});
    save(plan_id, "running", "", progress);
    plan_event(plan_id, "plan.step", {{"step", step_index + 1}, {"profile", step.profile}, {"run_id", *run}, {"units", units}});
    return false;
  }

  const auto run_id = progress["run_id"].get<std::int64_t>();
  if (runs_.active_run_id() == run_id) return false;
  if (runs_.resuming_run_id() == run_id) return false;  // its stored seconds being replayed
  auto detail = store_.get_run(run_id);
  if (!detail) return false;
  const auto state = detail->run.state;
  if (state == storage::RunState::interrupted || state == storage::RunState::pending) {
    // The daemon stopped during the step: the run is taken up again as run.resume does.
    json command = {{"cmd", "plan.resume"}, {"plan_id", plan_id}, {"run_id", run_id}};
    // The stored seconds are replayed off the loop (RunControl::resume_run_async); the plan goes
    // on once the run is taken up. Refused `busy` or `unavailable`: tried again at a later tick.
    const bool skip = !analysed(step.purpose);
    runs_.resume_run_async(run_id, wall_time, command, {JobClass::station, {}},
                           [this, plan_id, run_id, step_index, skip](ApiResult<std::int64_t> r) {
      if (r && skip) runs_.skip_analysis(run_id);
      if (r) {
        plan_event(plan_id, "plan.resume", {{"step", step_index + 1}, {"run_id", run_id}});
        spdlog::info("plan {}: run {} of step {} resumed", plan_id, run_id, step_index + 1);
      } else if (r.error().code != ErrorCode::unavailable && r.error().code != ErrorCode::busy) {
        auto now_rec = store_.get_plan(plan_id);
        if (!now_rec || now_rec->state != "running") return;  // aborted meanwhile
        json now = json::parse(now_rec->progress_json, nullptr, false);
        if (!now.is_object()) return;
        finish_plan(plan_id, now, "failed", "run " + std::to_string(run_id) + " could not resume: " + r.error().message);
      }
    });
    return false;
  }
  if (state != storage::RunState::completed) {
    finish_plan(plan_id, progress, state == storage::RunState::aborted ? "aborted" : "failed",
                "step " + std::to_string(step_index + 1) + " (" + step.profile + "): run " + std::to_string(run_id) + " " +
                    std::string(storage::to_string(state)) + ": " + detail->run.state_reason);
    return false;
  }
  // Completed: wait until every unit's automatic analysis has been stored (its note event).
  json notes = json::array();
  if (!analysed(step.purpose))  // nothing to wait for: every unit of the run as if noted
    for (const auto& ru : detail->run.units) notes.push_back({{"unit", ru.unit_index}, {"serial", ru.serial}, {"ok", true}});
  for (const auto& e : detail->events) {
    if (!analysed(step.purpose)) break;
    if (e.kind != storage::EventKind::note) continue;
    json d = json::parse(e.detail_json, nullptr, false);
    if (d.is_object() && d.contains("analysis") && d.contains("unit")) notes.push_back(d);
  }
  if (notes.size() < detail->run.units.size()) {
    if (!runs_.analysing(run_id)) {
      // Nobody computes it: the daemon was killed between the run's end and the storage of its
      // analysis. Done again now from the stored samples, for the units without a note (the
      // units with one keep theirs); a failure is noted and judged as any failed analysis.
      std::vector<std::string> serials;
      std::vector<int> missing;
      for (const auto& ru : detail->run.units) {
        serials.push_back(ru.serial);
        const bool noted = std::any_of(notes.begin(), notes.end(), [&](const json& n) {
          return n["unit"].is_number_integer() && n["unit"].get<int>() == ru.unit_index;
        });
        if (!noted) missing.push_back(ru.unit_index);
      }
      plan_event(plan_id, "plan.analysis",
                 {{"step", step_index + 1}, {"run_id", run_id}, {"units", missing},
                  {"reason", "the run completed but its analysis was never stored (the daemon stopped)"}});
      spdlog::warn("plan {}: run {} of step {} completed without its analysis stored: analysing it again", plan_id,
                   run_id, step_index + 1);
      runs_.analyse_units(run_id, detail->run.purpose, serials, missing);
    }
    // Saved (once, when it changes), so that status, also after a restart, shows what the plan
    // waits for; not saved every tick while it stays the same.
    if (progress.value("waiting", json()) != "analysis") {
      progress["waiting"] = "analysis";
      save(plan_id, "running", "", progress);
    }
    return false;
  }
  judge(plan_id, progress, *plan, notes, run_id);
  // The units that must run the step again, if any; else the next step.
  json retest = json::array();
  for (auto& u : progress["units"])
    if (u.value("retest_step", -1) == static_cast<int>(step_index) && u["active"].get<bool>() &&
        u.value("retested", false) == false)
      retest.push_back(u["serial"]);
  if (!retest.empty() && progress["attempt"].get<int>() == 0) {
    for (auto& u : progress["units"])
      if (std::find(retest.begin(), retest.end(), u["serial"]) != retest.end()) u["retested"] = true;
    progress["attempt"] = 1;
    progress["step_units"] = retest;
  } else {
    for (auto& u : progress["units"]) u.erase("retested");
    progress["step"] = step_index + 1;
    progress["attempt"] = 0;
    progress["step_units"] = nullptr;
  }
  progress["run_id"] = nullptr;
  progress["waiting"] = "start";
  save(plan_id, "running", "", progress);
  return true;
}

void PlanRunner::judge(std::int64_t plan_id, json& progress, const plans::Plan& plan, const json& notes,
                       std::int64_t run_id) {
  const auto step_index = progress["step"].get<std::size_t>();
  const plans::Step& step = plan.steps[step_index];
  const bool retest_attempt = progress["attempt"].get<int>() > 0;
  auto& store = store_;
  const auto run_rec = store.get_run(run_id);
  // Whether this step's run had rate steps: its profile as run (stored with the run).
  const bool rate_run = run_rec && has_rate_steps(run_rec->run.profile_text, step.profile + ".profile");
  std::optional<std::vector<storage::VerificationRecord>> verifications;
  for (const auto& note : notes) {
    const int unit_index = note["unit"].get<int>();
    const std::string serial = note.value("serial", "");
    json* u = find_unit(progress, serial);
    if (!u) continue;
    // A three-axis unit is judged on each of its axes against every limit (its progress keeps
    // each axis' evidence: axis_evidence); a one-axis unit on its only one, as it always was.
    const bool three = run_rec && unit_index >= 0 && static_cast<std::size_t>(unit_index) < run_rec->run.units.size() &&
                       run_rec->run.units[static_cast<std::size_t>(unit_index)].axes == 3;
    if (three && !u->contains("axis_evidence")) {
      (*u)["axis_evidence"] = json::object();
      for (const char* a : {"x", "y", "z"}) (*u)["axis_evidence"][a] = {{"verdict", "pass"}, {"reasons", json::array()}};
    }
    // What a failure on an axis makes of that axis (the unit's own verdict follows the plan's flow
    // below; the two agree: an axis fails exactly when its failure drops the unit).
    auto axis_outcome = [&](const std::string& axis, const std::string& verdict_of_axis, const std::string& why) {
      json& e = (*u)["axis_evidence"][axis];
      if (!verdict_of_axis.empty()) e["verdict"] = verdict::worst(e["verdict"].get<std::string>(), verdict_of_axis);
      e["reasons"].push_back(why);
    };
    auto drop = [&](const std::string& why) {
      (*u)["active"] = false;
      (*u)["verdict"] = "fail";
      (*u)["reasons"].push_back(why);
      plan_event(plan_id, "plan.unit", {{"run_id", run_id}, {"serial", serial}, {"verdict", "fail"}, {"why", why}});
      // Its verdict is final: certified fail from now; a three-axis unit's once every limit of the
      // step has been judged on each axis (below), so that its axes' evidence is whole.
      if (!three) decide_unit(plan_id, progress, *u);
    };
    const std::string where = "step " + std::to_string(step_index + 1) + " (" + step.profile + ", run " +
                              std::to_string(run_id) + ")";
    if (!note.value("ok", false) && (step.purpose == plans::StepPurpose::fit || step.purpose == plans::StepPurpose::verify)) {
      const std::string why =
          where + ": the " + note.value("analysis", std::string("analysis")) + " failed: " + note.value("error", "");
      if (three) {  // the axes whose analysis failed, each; every axis when the note names none
        bool named = false;
        if (note.contains("axes") && note["axes"].is_array())
          for (const auto& a : note["axes"])
            if (a.is_object() && a.value("ok", true) == false && a.contains("axis") && a["axis"].is_string() &&
                (*u)["axis_evidence"].contains(a["axis"].get<std::string>())) {
              named = true;
              axis_outcome(a["axis"].get<std::string>(), "fail",
                           where + ": the " + note.value("analysis", std::string("analysis")) + " failed: " + a.value("error", ""));
            }
        if (!named)
          for (const char* a : {"x", "y", "z"}) axis_outcome(a, "fail", why);
      }
      drop(why);
      if (three) decide_unit(plan_id, progress, *u);
      continue;
    }
    // The measurements of this step for this unit, on each axis judged.
    struct AxisMeasures {
      std::optional<model::Axis> axis;  // none: a one-axis unit
      std::optional<model::Model> fitted, verified_model;
      json verification;
      std::optional<model::RunData> data;
      bool data_read = false;
      std::optional<plan_figures::AllanFigures> allan;
      std::optional<plan_figures::SfFigures> sf;  // the run's scale-factor fit, made once for every sf_* limit
    };
    std::vector<AxisMeasures> measures;
    if (three) {
      for (const auto a : {model::Axis::x, model::Axis::y, model::Axis::z}) measures.push_back({a, {}, {}, {}, {}, false, {}, {}});
    } else {
      measures.push_back({});
    }
    std::optional<model::RunData> whole;  // the unit's run as stored, read once
    bool whole_read = false;
    for (auto& am : measures) {
      // The note's figures of this axis: a three-axis unit's in its `axes`, a one-axis unit's at its top.
      json of_axis = note;
      if (am.axis && note.contains("axes") && note["axes"].is_array())
        for (const auto& a : note["axes"])
          if (a.is_object() && a.value("axis", "") == model::to_string(*am.axis)) of_axis = a;
      if (am.axis && of_axis.value("axis", "") != model::to_string(*am.axis)) of_axis = json::object();  // not in the note
      if (step.purpose == plans::StepPurpose::fit && of_axis.contains("model_id") && of_axis["model_id"].is_number_integer()) {
        auto m = store.get_model(of_axis["model_id"].get<std::int64_t>());
        if (m) {
          auto mm = model::model_from_text(m->model_json);
          if (mm) am.fitted = std::move(*mm);
        }
      }
      if (step.purpose == plans::StepPurpose::verify && of_axis.contains("verification_id") &&
          of_axis["verification_id"].is_number_integer()) {
        if (!verifications)
          if (auto vs = store.list_verifications(run_id)) verifications = std::move(*vs);
        if (verifications)
          for (const auto& v : *verifications)
            if (v.id == of_axis["verification_id"].get<std::int64_t>()) {
              am.verification = json::parse(v.result_json, nullptr, false);
              auto m = store.get_model(v.model_id);
              if (m) {
                auto mm = model::model_from_text(m->model_json);
                if (mm) am.verified_model = std::move(*mm);
              }
            }
      }
    }
    // The axis' samples: the unit's run, and of a three-axis unit that axis read as a one-axis
    // gyro's output (model::select_axis, as its analysis read it).
    auto load_data = [&](AxisMeasures& am) -> const model::RunData* {
      if (!am.data_read) {
        am.data_read = true;
        if (!whole_read) {
          whole_read = true;
          if (auto d = store.export_run(run_id, unit_index)) whole = std::move(*d);
        }
        if (whole) {
          if (!am.axis) am.data = *whole;
          else if (auto s = model::select_axis(*whole, *am.axis)) am.data = std::move(*s);
        }
      }
      return am.data ? &*am.data : nullptr;
    };
    for (const plans::Limit& l : plan.limits) {
      if (!plans::measured_in(l.measurement, step.purpose)) continue;
      // Measured only where the table turned (a profile without rate steps has no scale factor).
      if (plans::needs_rate_steps(l.measurement) && !rate_run) continue;
      std::vector<std::string> failed_on;  // what failed, per axis: "axis y: comp_raw = 0.8212"
      for (auto& am : measures) {
        // The scale factor is the table's axis': a three-axis unit's x (its y and z lie across the
        // table's axis and see no rate).
        if (plans::needs_rate_steps(l.measurement) && am.axis && *am.axis != model::Axis::x) continue;
        const json& verification = am.verification;
        std::optional<double> value;
        std::string note_text;
        switch (l.measurement) {
          case plans::Measurement::comp_raw:
            if (verification.contains("ratio") && verification["ratio"].is_number()) value = verification["ratio"].get<double>();
            break;
          case plans::Measurement::noise_factor:
            if (verification.contains("noise_factor") && verification["noise_factor"].is_number())
              value = verification["noise_factor"].get<double>();
            break;
          case plans::Measurement::fail_s:
            if (verification.contains("longest_fail_s") && verification["longest_fail_s"].is_number())
              value = verification["longest_fail_s"].get<double>();
            break;
          case plans::Measurement::peak_excursion:
            if (am.verified_model)
              if (const auto* d = load_data(am)) value = plan_figures::peak_excursion_dph(*am.verified_model, *d);
            break;
          case plans::Measurement::sensitivity:
            if (am.fitted) {
              for (const auto& t : am.fitted->terms)
                if (t.name() == l.term) value = t.coef;
              if (!value) note_text = "the model has no term " + l.term + " (terms: " + am.fitted->terms_string() + ")";
            }
            break;
          case plans::Measurement::arw:
          case plans::Measurement::bias_instability:
            if (!am.allan)
              if (const auto* d = load_data(am)) am.allan = plan_figures::allan_figures(*d);
            if (am.allan) {
              value = l.measurement == plans::Measurement::arw ? am.allan->arw : am.allan->bias_instability;
              if (!value) note_text = am.allan->note;
            }
            break;
          case plans::Measurement::firmware:
            // The fitted model compiles to the firmware form (lags the firmware can meet); why not
            // is the note (the term and its lag).
            if (am.fitted) {
              auto program = model::firmware::compile(*am.fitted);
              value = program ? 1.0 : 0.0;
              if (!program) note_text = program.error();
            }
            break;
          case plans::Measurement::sf_tc_ppm_per_c:
          case plans::Measurement::sf_nonlinearity_ppm:
          case plans::Measurement::sf_asymmetry_ppm:
            // A fit that fails (no rate data, too few plateaus) gives no value: the limit is not met
            // and the note says why.
            if (!am.sf)
              if (const auto* d = load_data(am)) am.sf = plan_figures::sf_figures(*d);
            if (!am.sf) {
              note_text = "the run's samples could not be read";
            } else if (l.measurement == plans::Measurement::sf_tc_ppm_per_c) {
              value = am.sf->abs_tc_ppm_per_c;
              note_text = am.sf->tc_note;
            } else if (l.measurement == plans::Measurement::sf_nonlinearity_ppm) {
              value = am.sf->nonlinearity_ppm;
              note_text = am.sf->nonlinearity_note;
            } else {
              value = am.sf->abs_asymmetry_ppm;
              note_text = am.sf->asymmetry_note;
            }
            break;
        }
        const bool met = value && l.met(*value);
        json m = {{"step", step_index + 1}, {"profile", step.profile}, {"run_id", run_id}, {"measurement", l.name()},
                  {"value", value ? json(*value) : json(nullptr)}, {"unit", std::string(plans::unit_of(l.measurement))},
                  {"limit", l.describe()}, {"line", l.line}, {"met", met},
                  {"on_fail", std::string(plans::to_string(l.on_fail))}, {"attempt", retest_attempt ? 2 : 1}};
        if (!note_text.empty()) m["note"] = note_text;
        if (am.axis) m["axis"] = std::string(model::to_string(*am.axis));
        (*u)["measurements"].push_back(m);
        if (met) continue;
        const std::string measured =
            l.measurement == plans::Measurement::firmware
                ? (value ? "no firmware form (" + note_text + ")" : std::string("no model"))
                : l.name() + " = " + (value ? plan_figures::short_number(*value) : std::string("not measured")) +
                      (plans::needs_rate_steps(l.measurement) && !note_text.empty() ? " (" + note_text + ")" : std::string());
        if (am.axis) {
          // The axis' own evidence, judged whether or not the unit is still active: what its
          // failure makes of the axis by the limit's on_fail, as it makes of the unit below.
          const std::string axis(model::to_string(*am.axis));
          const std::string axis_why = where + ": " + measured + ", limit " + l.describe() + " (line " + std::to_string(l.line) + ")";
          if (l.on_fail == plans::OnFail::go_on) axis_outcome(axis, "marginal", axis_why + ": marginal");
          else if (l.on_fail == plans::OnFail::retest && !retest_attempt) axis_outcome(axis, "", axis_why + ": retest once");
          else axis_outcome(axis, "fail", axis_why + (l.on_fail == plans::OnFail::retest ? ": failed its retest too" : ""));
          failed_on.push_back("axis " + axis + ": " + measured);
        } else {
          failed_on.push_back(measured);
        }
      }
      if (failed_on.empty() || !(*u)["active"].get<bool>()) continue;
      std::string measured;
      for (const auto& f : failed_on) measured += (measured.empty() ? "" : "; ") + f;
      const std::string why = where + ": " + measured + ", limit " + l.describe() + " (line " + std::to_string(l.line) + ")";
      if (l.on_fail == plans::OnFail::go_on) {
        (*u)["marginal"] = true;
        (*u)["reasons"].push_back(why + ": marginal, goes on");
      } else if (l.on_fail == plans::OnFail::retest && !retest_attempt) {
        (*u)["retest_step"] = static_cast<int>(step_index);
        (*u)["reasons"].push_back(why + ": retest once");
      } else {
        drop(why + (l.on_fail == plans::OnFail::retest ? ": failed its retest too" : ""));
      }
    }
    // A unit that was to retest but then hit a stop-limit is not retested.
    if (!(*u)["active"].get<bool>()) u->erase("retest_step");
    if (three && !(*u)["active"].get<bool>()) {
      // Steps left after this one: the axes that met every limit were not measured to the end.
      if (step_index + 1 < progress["steps"].get<std::size_t>()) (*u)["dropped_at_step"] = static_cast<int>(step_index + 1);
      decide_unit(plan_id, progress, *u);
    }
  }
}

}  // namespace fogbench::daemon
