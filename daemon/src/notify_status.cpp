// systemd's STATUS= line while fogbenchd runs (notify_status.hpp, docs/daemon.md).
#include "notify_status.hpp"

#include <cmath>

#include "fogbench/daemon/plan_runner.hpp"
#include "fogbench/daemon/station.hpp"

namespace fogbench::daemon {

using nlohmann::json;

namespace {

std::string seconds(const json& v) {
  if (!v.is_number()) return "?";
  return std::to_string(std::llround(v.get<double>()));
}

std::string str(const json& v) { return v.is_string() ? v.get<std::string>() : std::string(); }

}  // namespace

std::string status_text(const json& status, const json& plan, const json& last_run, std::string* key) {
  std::string text, k;
  if (plan.is_object()) {
    const json& p = plan.contains("progress") && plan["progress"].is_object() ? plan["progress"] : json::object();
    const auto step = p.value("step", json(nullptr));
    const auto steps = p.value("steps", json(nullptr));
    text = "plan " + std::to_string(plan.value("plan_id", std::int64_t{0})) + " " + str(plan.value("name", json(""))) +
           " step " + (step.is_number_integer() ? std::to_string(step.get<std::int64_t>() + 1) : std::string("?")) + "/" +
           (steps.is_number_integer() ? std::to_string(steps.get<std::int64_t>()) : std::string("?"));
    const std::string waiting = str(p.value("waiting", json(nullptr)));
    k = text + "|" + waiting;
    if (!status.contains("run") || status["run"].is_null()) text += waiting.empty() ? "" : ", waiting for the " + waiting;
    text += ": ";
  }
  const json run = status.value("run", json(nullptr));
  if (run.is_object()) {
    const std::string state = str(run.value("state", json("")));
    const std::string phase = str(run.value("phase", json(nullptr)));
    const auto step = run.value("step", json(nullptr));
    const auto steps = run.value("steps", json(nullptr));
    std::string line = "run " + std::to_string(run.value("id", std::int64_t{0})) + " " + str(run.value("profile", json(""))) +
                       " " + state;
    if (step.is_number_integer() && state != "pending") {
      line += " step " + std::to_string(step.get<std::int64_t>() + 1);
      if (steps.is_number_integer()) line += "/" + std::to_string(steps.get<std::int64_t>());
      if (!phase.empty()) line += " (" + phase + ")";
    }
    k += "|" + line;
    const json elapsed = run.value("elapsed_s", json(nullptr));
    const json remaining = run.value("remaining_s", json(nullptr));
    line += ", " + seconds(elapsed) + "/";
    line += elapsed.is_number() && remaining.is_number()
                ? std::to_string(std::llround(elapsed.get<double>() + remaining.get<double>()))
                : std::string("?");
    line += " s";
    if (run.contains("units") && run["units"].is_array()) {
      line += ",";
      for (const auto& u : run["units"]) line += " " + str(u);
    }
    text += line;
  } else if (!plan.is_object()) {
    text = "idle";
    if (last_run.is_object())
      text += ", last run " + std::to_string(last_run.value("id", std::int64_t{0})) + " " +
              str(last_run.value("profile", json(""))) + " " + str(last_run.value("state", json("")));
    else
      text += ", no run stored";
    k = text;
  }
  if (const json ch = status.value("chamber", json(nullptr)); ch.is_object() && str(ch.value("link", json(""))) == "down") {
    text += "; chamber link down";
    k += "|link down";
  }
  if (key) *key = k;
  return text;
}

StatusNotifier::StatusNotifier(boost::asio::io_context& io, Station& station, PlanRunner* plans, Send send)
    : timer_(io), station_(station), plans_(plans), send_(std::move(send)) {}

void StatusNotifier::start() { look(); }

void StatusNotifier::stop() {
  stopped_ = true;
  timer_.cancel();
}

void StatusNotifier::schedule() {
  if (stopped_) return;
  timer_.expires_after(kLook);
  timer_.async_wait([this](boost::system::error_code ec) {
    if (!ec && !stopped_) look();
  });
}

void StatusNotifier::look() {
  const json status = station_.status();
  json plan = nullptr;
  if (plans_)
    if (auto id = plans_->running_plan_id())
      if (auto p = plans_->status(*id)) plan = std::move(*p);
  // The newest stored run, for the idle line: read again only when a run has ended since (the
  // station's last_run changed), not at every look.
  const json ended = status.value("last_run", json(nullptr));
  if (!plan.is_object() && status.value("run", json(nullptr)).is_null() && (!last_read_ || ended != last_ended_)) {
    storage::RunFilter f;
    f.limit = 1;
    auto runs = station_.store().list_runs(f);
    if (runs) {
      last_run_ = runs->empty() ? json(nullptr)
                                : json{{"id", runs->front().id},
                                       {"profile", runs->front().profile_name},
                                       {"state", std::string(storage::to_string(runs->front().state))}};
      last_ended_ = ended;
      last_read_ = true;
    }
  }
  std::string key;
  const std::string text = status_text(status, plan, last_run_, &key);
  const auto now = std::chrono::steady_clock::now();
  const bool changed_kind = key != sent_key_;
  const bool due = !sent_at_ || now - *sent_at_ >= kEvery;
  if (changed_kind || (due && text != sent_text_)) {
    send_("STATUS=" + text);
    sent_key_ = key;
    sent_text_ = text;
    sent_at_ = now;
  }
  schedule();
}

}  // namespace fogbench::daemon
