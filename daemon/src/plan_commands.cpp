// The plan.* and queue.* socket commands (docs/protocol.md): arguments checked here, the work
// done by the PlanRunner (plan_runner.hpp).
#include <string>
#include <vector>

#include "fogbench/daemon/plan_runner.hpp"
#include "fogbench/daemon/station.hpp"
#include "fogbench/storage/identity.hpp"

namespace fogbench::daemon {

using nlohmann::json;

namespace {

ApiResult<std::string> string_field(const json& req, const char* key, bool required) {
  if (!req.contains(key)) {
    if (required) return api_error(ErrorCode::bad_request, std::string(key) + ": missing");
    return std::string();
  }
  if (!req[key].is_string()) return api_error(ErrorCode::bad_request, std::string(key) + ": expected a string");
  return req[key].get<std::string>();
}

ApiResult<std::int64_t> id_field(const json& req, const char* key) {
  if (!req.contains(key)) return api_error(ErrorCode::bad_request, std::string(key) + ": missing");
  if (!req[key].is_number_integer() || req[key].get<std::int64_t>() < 1)
    return api_error(ErrorCode::bad_request, std::string(key) + ": expected a positive integer");
  return req[key].get<std::int64_t>();
}

// The plan as sent: its text (`text`, the file's content) and where it came from (`source`,
// for the line errors), and the units.
struct PlanArgs {
  std::string text, source;
  std::vector<std::string> units;
  std::map<std::string, std::string> slots;  // serial -> bench slot, for every unit
};
// `units` and `slots` read as run.start's (bench_slots.hpp).
ApiResult<PlanArgs> plan_args(const json& req, bool units_required, const std::vector<drivers::UnitConfig>& configured) {
  PlanArgs a;
  auto text = string_field(req, "text", true);
  if (!text) return std::unexpected(text.error());
  a.text = *text;
  auto source = string_field(req, "source", false);
  if (!source) return std::unexpected(source.error());
  if (auto why = storage::check_stored_text("source", *source, storage::kMaxSourceBytes); !why.empty())
    return api_error(ErrorCode::bad_request, why);
  a.source = source->empty() ? "plan" : *source;
  auto units = slot_units(req, configured, units_required);
  if (!units) return std::unexpected(units.error());
  a.units = serials_of(*units);
  for (const auto& u : *units) a.slots[u.serial] = configured[u.config_index].slot;
  return a;
}

// The operator (`operator`, else the unix peer's user, as run.start) and the lots (`lot` for
// every unit or `lots` {serial: lot}, checked as run.start's).
ApiResult<PlanTrace> plan_trace(const json& req, const std::vector<std::string>& units, const std::string& peer_user) {
  PlanTrace t;
  auto op = operator_of(req, peer_user);
  if (!op) return std::unexpected(op.error());
  t.op = std::move(*op);
  auto lots = Station::unit_lots(req, units);
  if (!lots) return std::unexpected(lots.error());
  for (std::size_t i = 0; i < units.size(); ++i)
    if ((*lots)[i]) t.lots[units[i]] = *(*lots)[i];
  return t;
}

std::unexpected<ApiError> no_plans(const std::string& cmd) {
  return api_error(ErrorCode::unavailable, cmd + ": this station runs no plans");
}

}  // namespace

ApiResult<json> plan_validate(PlanRunner* runner, const std::string& cmd, const json& req) {
  if (!runner) return no_plans(cmd);
  auto a = plan_args(req, false, runner->bench_slots());
  if (!a) return std::unexpected(a.error());
  // Without units: the text and the profiles only (no unit, no model on file checked).
  return runner->validate(a->text, a->source, a->units, a->slots);
}

json plan_trace_json(const std::string& operator_name, const std::string& operator_source,
                     const std::map<std::string, std::string>& lots) {
  return {{"operator", operator_name}, {"operator_source", operator_source}, {"lots", lots}};
}

ApiResult<json> plan_start(PlanRunner* runner, const std::string& cmd, const json& req, const std::string& peer_user) {
  if (!runner) return no_plans(cmd);
  auto a = plan_args(req, true, runner->bench_slots());
  if (!a) return std::unexpected(a.error());
  auto t = plan_trace(req, a->units, peer_user);
  if (!t) return std::unexpected(t.error());
  t->slots = a->slots;
  return runner->start(a->text, a->source, a->units, *t, req);
}

ApiResult<json> queue_add(PlanRunner* runner, const std::string& cmd, const json& req, const std::string& peer_user) {
  if (!runner) return no_plans(cmd);
  auto a = plan_args(req, true, runner->bench_slots());
  if (!a) return std::unexpected(a.error());
  auto t = plan_trace(req, a->units, peer_user);
  if (!t) return std::unexpected(t.error());
  t->slots = a->slots;
  return runner->queue_add(a->text, a->source, a->units, *t, req);
}

ApiResult<json> plan_status(PlanRunner* runner, const std::string& cmd, const json& req) {
  if (!runner) return no_plans(cmd);
  std::optional<std::int64_t> id;
  if (req.contains("plan_id")) {
    auto i = id_field(req, "plan_id");
    if (!i) return std::unexpected(i.error());
    id = *i;
  }
  return runner->status(id);
}

ApiResult<json> plan_abort(PlanRunner* runner, const std::string& cmd, const json& req) {
  if (!runner) return no_plans(cmd);
  auto reason = string_field(req, "reason", false);
  if (!reason) return std::unexpected(reason.error());
  if (auto why = storage::check_stored_text("reason", *reason, storage::kMaxReasonBytes); !why.empty())
    return api_error(ErrorCode::bad_request, why);
  return runner->abort(*reason, req);
}

ApiResult<json> queue_list(PlanRunner* runner, const std::string& cmd, const json&) {
  if (!runner) return no_plans(cmd);
  return runner->queue_list();
}

ApiResult<json> queue_remove(PlanRunner* runner, const std::string& cmd, const json& req) {
  if (!runner) return no_plans(cmd);
  auto i = id_field(req, "plan_id");
  if (!i) return std::unexpected(i.error());
  return runner->queue_remove(*i, req);
}

ApiResult<json> queue_move(PlanRunner* runner, const std::string& cmd, const json& req) {
  if (!runner) return no_plans(cmd);
  auto i = id_field(req, "plan_id");
  if (!i) return std::unexpected(i.error());
  auto pos = id_field(req, "position");
  if (!pos) return std::unexpected(pos.error());
  return runner->queue_move(*i, *pos, req);
}

}  // namespace fogbench::daemon
