// The plans' queue (plan_runner.hpp, docs/plans.md): list, add, remove and move
// queued plans. The runner (plan_runner.cpp) takes the next queued plan when none runs.
#include <algorithm>

#include "fogbench/daemon/plan_runner.hpp"
#include "fogbench/storage/plans.hpp"

namespace fogbench::daemon {

using nlohmann::json;

ApiResult<json> PlanRunner::queue_list() const {
  auto q = store_.list_plans("queued");
  if (!q) return std::unexpected(from_store(q.error()));
  json arr = json::array();
  std::int64_t pos = 1;
  for (const auto& p : *q)
    arr.push_back({{"position", pos++}, {"plan_id", p.id}, {"name", p.name}, {"source", p.source}, {"units", p.units},
                   {"created_at", p.created_at}, {"operator", p.operator_name}, {"operator_source", p.operator_source},
                   {"lots", p.lots}, {"slots", p.slots}});
  json j = {{"queue", arr}};
  auto running = running_plan_id();
  j["running"] = running ? json(*running) : json(nullptr);
  return j;
}

ApiResult<json> PlanRunner::queue_add(const std::string& text, const std::string& source,
                                      const std::vector<std::string>& units, const PlanTrace& trace,
                                      const json& command) {
  if (units.empty()) return api_error(ErrorCode::bad_request, "units: expected at least one serial");
  auto p = check(text, source, units, trace.slots);
  if (!p) return std::unexpected(p.error());
  storage::NewPlan np{p->name, source, text, units, "queued", trace.op.name, trace.op.source, trace.lots, trace.slots};
  json detail = command;
  detail.update(plan_trace_json(trace.op.name, trace.op.source, trace.lots));
  auto id = store_.create_plan(np, "queue.add", detail.dump());
  if (!id) return std::unexpected(from_store(id.error()));
  auto q = queue_list();
  if (!q) return q;
  json& queue = (*q)["queue"];
  return json{{"plan_id", *id}, {"name", p->name}, {"state", "queued"}, {"position", queue.size()}};
}

namespace {
// The queued ids in order, or an error naming the plan when it is not queued.
ApiResult<std::vector<std::int64_t>> queued_ids(storage::Store& store, std::int64_t plan_id, const char* what) {
  auto q = store.list_plans("queued");
  if (!q) return std::unexpected(from_store(q.error()));
  std::vector<std::int64_t> ids;
  for (const auto& p : *q) ids.push_back(p.id);
  if (std::find(ids.begin(), ids.end(), plan_id) == ids.end()) {
    auto p = store.get_plan(plan_id);
    if (!p) return api_error(ErrorCode::not_found, "plan_id: no plan " + std::to_string(plan_id));
    return api_error(p->state == "running" ? ErrorCode::busy : ErrorCode::bad_request,
                     std::string("plan_id: plan ") + std::to_string(plan_id) + " is " + p->state + ", not queued: " + what +
                         " only a queued plan (plan.abort stops a running one)");
  }
  return ids;
}
}  // namespace

ApiResult<json> PlanRunner::queue_remove(std::int64_t plan_id, const json& command) {
  auto ids = queued_ids(store_, plan_id, "queue.remove takes out");
  if (!ids) return std::unexpected(ids.error());
  std::erase(*ids, plan_id);
  if (auto ok = store_.set_queue(*ids, plan_id, "queue.remove", command.dump()); !ok)
    return std::unexpected(from_store(ok.error()));
  return json{{"plan_id", plan_id}, {"state", "aborted"}, {"reason", "removed from the queue"}};
}

ApiResult<json> PlanRunner::queue_move(std::int64_t plan_id, std::int64_t position, const json& command) {
  auto ids = queued_ids(store_, plan_id, "queue.move moves");
  if (!ids) return std::unexpected(ids.error());
  if (position < 1 || position > static_cast<std::int64_t>(ids->size()))
    return api_error(ErrorCode::bad_request, "position: expected 1.." + std::to_string(ids->size()) + ", found " +
                                                 std::to_string(position));
  std::erase(*ids, plan_id);
  ids->insert(ids->begin() + (position - 1), plan_id);
  json detail = command;
  if (auto ok = store_.set_queue(*ids, std::nullopt, "queue.move", detail.dump()); !ok)
    return std::unexpected(from_store(ok.error()));
  return json{{"plan_id", plan_id}, {"position", position}, {"queue", *ids}};
}

}  // namespace fogbench::daemon
