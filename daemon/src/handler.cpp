// The command handler: request validation with messages that name the field, and one function
// per command. Every failure is an error reply; nothing here throws to the caller.
#include "fogbench/daemon/handler.hpp"

#include <chrono>
#include <cmath>

#include "fogbench/daemon/framing.hpp"
#include "fogbench/model/json.hpp"

namespace fogbench::daemon {

using nlohmann::json;

namespace {

json num(double v) {
  if (!std::isfinite(v)) return nullptr;
  return v;
}

// Field accessors: absent is fine for optional ones; present with the wrong type is not.
ApiResult<std::optional<std::string>> opt_string(const json& req, const char* key) {
  if (!req.contains(key) || req[key].is_null()) return std::optional<std::string>{};
  if (!req[key].is_string()) return api_error(ErrorCode::bad_request, std::string(key) + ": expected a string");
  return std::optional<std::string>(req[key].get<std::string>());
}
ApiResult<std::string> req_string(const json& req, const char* key) {
  auto s = opt_string(req, key);
  if (!s) return std::unexpected(s.error());
  if (!*s || (*s)->empty()) return api_error(ErrorCode::bad_request, std::string(key) + ": missing");
  return **s;
}
ApiResult<std::optional<std::int64_t>> opt_int(const json& req, const char* key, std::int64_t min,
                                               std::int64_t max) {
  if (!req.contains(key) || req[key].is_null()) return std::optional<std::int64_t>{};
  const json& v = req[key];
  if (!v.is_number_integer() || v.get<std::int64_t>() < min || v.get<std::int64_t>() > max)
    return api_error(ErrorCode::bad_request, std::string(key) + ": expected an integer " +
                                                 std::to_string(min) + ".." + std::to_string(max));
  return std::optional<std::int64_t>(v.get<std::int64_t>());
}
ApiResult<std::int64_t> req_int(const json& req, const char* key, std::int64_t min, std::int64_t max) {
  auto v = opt_int(req, key, min, max);
  if (!v) return std::unexpected(v.error());
  if (!*v) return api_error(ErrorCode::bad_request, std::string(key) + ": missing");
  return **v;
}

constexpr std::int64_t kMaxId = std::numeric_limits<std::int64_t>::max();

json run_json(const storage::RunRecord& r) {
  json units = json::array();
  for (const auto& u : r.units) units.push_back(u.serial);
  return {{"id", r.id}, {"created_at", r.created_at}, {"profile", r.profile_name},
          {"purpose", std::string(storage::to_string(r.purpose))},
          {"state", std::string(storage::to_string(r.state))}, {"reason", r.state_reason},
          {"started_at", r.started_at ? json(*r.started_at) : json(nullptr)},
          {"ended_at", r.ended_at ? json(*r.ended_at) : json(nullptr)},
          {"time_scale", r.time_scale}, {"units", units}};
}

json parse_or_string(const std::string& text) {
  json j = json::parse(text, nullptr, false);
  return j.is_discarded() ? json(text) : j;
}

json model_json(const storage::ModelRecord& m) {
  return {{"id", m.id}, {"serial", m.serial}, {"version", m.version},
          {"run_id", m.run_id ? json(*m.run_id) : json(nullptr)},
          {"parent_id", m.parent_id ? json(*m.parent_id) : json(nullptr)},
          {"created_at", m.created_at}, {"method", m.method}, {"terms", m.terms},
          {"model", parse_or_string(m.model_json)}};
}

json sample_json(const storage::SampleRow& r) {
  return {{"t_s", r.t_s}, {"wall_time", num(r.wall_time)}, {"setpoint_c", num(r.setpoint_c)},
          {"chamber_c", num(r.chamber_c)}, {"gyro_dph", num(r.gyro_dph)},
          {"frames", r.frames ? json(*r.frames) : json(nullptr)}, {"t1_c", num(r.t1_c)},
          {"t2_c", num(r.t2_c)}, {"phase", std::string(model::to_string(r.phase))},
          {"step", r.step ? json(*r.step) : json(nullptr)}, {"flags", r.flags}};
}

ApiError store_error(const storage::StoreError& e) {
  if (e.code == storage::StoreErrc::not_found) return {ErrorCode::not_found, e.message};
  return {ErrorCode::internal, std::string(storage::to_string(e.code)) + ": " + e.message};
}

// `unit` is an index into the run's units or a serial; absent means the first unit.
ApiResult<int> resolve_unit(storage::Store& store, std::int64_t run_id, const json& req) {
  auto run = store.get_run(run_id);
  if (!run) return std::unexpected(store_error(run.error()));
  const auto& units = run->run.units;
  if (!req.contains("unit") || req["unit"].is_null()) {
    if (units.empty()) return api_error(ErrorCode::not_found, "run " + std::to_string(run_id) + " has no units");
    return 0;
  }
  const json& u = req["unit"];
  if (u.is_number_integer()) {
    const auto i = u.get<std::int64_t>();
    if (i < 0 || i >= static_cast<std::int64_t>(units.size()))
      return api_error(ErrorCode::not_found, "run " + std::to_string(run_id) + " has no unit " + std::to_string(i));
    return static_cast<int>(i);
  }
  if (u.is_string()) {
    for (const auto& ru : units)
      if (ru.serial == u.get<std::string>()) return ru.unit_index;
    return api_error(ErrorCode::not_found, "run " + std::to_string(run_id) + " has no unit " + u.get<std::string>());
  }
  return api_error(ErrorCode::bad_request, "unit: expected an index or a serial");
}

}  // namespace

bool is_control_command(std::string_view cmd) {
  return cmd == "run.start" || cmd == "run.abort" || cmd == "run.resume" || cmd == "model.fit" ||
         cmd == "model.verify" || cmd == "model.add_term";
}

namespace {
// In time independent of where the strings differ, so a remote client cannot find the token
// byte by byte from reply times.
bool same_token(const std::string& a, const std::string& b) {
  unsigned diff = a.size() == b.size() ? 0u : 1u;
  for (std::size_t i = 0; i < b.size(); ++i) diff |= static_cast<unsigned char>(i < a.size() ? a[i] : 0) ^ static_cast<unsigned char>(b[i]);
  return diff == 0;
}
}  // namespace

json Handler::hello() {
  return {{"type", "hello"}, {"version", FOGBENCH_DAEMON_VERSION}, {"protocol", kProtocolVersion},
          {"max_line_bytes", kMaxLineBytes}};
}

json Handler::reply(const json& id, json result) {
  return {{"type", "reply"}, {"id", id}, {"result", std::move(result)}};
}

json Handler::error(const json& id, ErrorCode code, const std::string& message) {
  return {{"type", "reply"}, {"id", id},
          {"error", {{"code", std::string(to_string(code))}, {"message", message}}}};
}

json Handler::too_long() {
  return error(nullptr, ErrorCode::bad_request,
               "line longer than " + std::to_string(kMaxLineBytes) + " bytes; closing");
}

json Handler::handle_line(std::string_view line, SessionState& session) {
  json req = json::parse(line, nullptr, false);
  if (req.is_discarded()) return error(nullptr, ErrorCode::bad_json, "not a JSON value");
  return handle(req, session);
}

json Handler::handle(const json& req, SessionState& session) {
  if (!req.is_object()) return error(nullptr, ErrorCode::bad_request, "expected a JSON object");
  json id = req.contains("id") ? req["id"] : json(nullptr);
  if (!id.is_null() && !id.is_number_integer() && !id.is_string())
    return error(nullptr, ErrorCode::bad_request, "id: expected an integer or a string");
  if (id.is_null()) return error(nullptr, ErrorCode::bad_request, "id: missing");
  if (!req.contains("cmd")) return error(id, ErrorCode::bad_request, "cmd: missing");
  if (!req["cmd"].is_string()) return error(id, ErrorCode::bad_request, "cmd: expected a string");
  const std::string cmd = req["cmd"].get<std::string>();
  // The token is a credential: checked here and never stored with the command in the audit trail.
  json request = req;
  json token = request.contains("token") ? request["token"] : json(nullptr);
  request.erase("token");
  if (!token.is_null() && !token.is_string()) return error(id, ErrorCode::bad_request, "token: expected a string");
  if (!session.may_control && is_control_command(cmd)) {
    if (session.control_token.empty())
      return error(id, ErrorCode::forbidden, cmd + ": only on the local socket; this connection may only read");
    if (token.is_null() || !same_token(token.get<std::string>(), session.control_token))
      return error(id, ErrorCode::forbidden, cmd + ": needs a valid token on this connection");
  }
  try {
    auto r = dispatch(cmd, request, session);
    if (!r) return error(id, r.error().code, r.error().message);
    return reply(id, std::move(*r));
  } catch (const std::exception& e) {
    // A bug, not an input: reported, and the daemon stays up.
    return error(id, ErrorCode::internal, e.what());
  }
}

ApiResult<json> Handler::dispatch(const std::string& cmd, const json& req, SessionState& session) {
  storage::Store& store = station_.store();

  if (cmd == "status") return station_.status();

  if (cmd == "subscribe") {
    session.subscribed = true;
    return json{{"subscribed", true}};
  }
  if (cmd == "unsubscribe") {
    session.subscribed = false;
    return json{{"subscribed", false}};
  }

  if (cmd == "run.start") {
    auto profile = req_string(req, "profile");
    if (!profile) return std::unexpected(profile.error());
    if (!req.contains("units")) return api_error(ErrorCode::bad_request, "units: missing");
    if (!req["units"].is_array()) return api_error(ErrorCode::bad_request, "units: expected an array of serials");
    std::vector<std::string> serials;
    for (const auto& u : req["units"]) {
      if (!u.is_string()) return api_error(ErrorCode::bad_request, "units: expected an array of serials");
      serials.push_back(u.get<std::string>());
    }
    auto purpose = opt_string(req, "purpose");
    if (!purpose) return std::unexpected(purpose.error());
    auto id = station_.start_run(*profile, serials, purpose->value_or("fit"), req);
    if (!id) return std::unexpected(id.error());
    return json{{"run_id", *id}, {"state", "pending"}};
  }

  if (cmd == "run.abort") {
    auto reason = opt_string(req, "reason");
    if (!reason) return std::unexpected(reason.error());
    auto run_id = opt_int(req, "run_id", 1, kMaxId);
    if (!run_id) return std::unexpected(run_id.error());
    auto active = station_.active_run_id();
    if (*run_id && active != *run_id)
      return api_error(ErrorCode::not_found, "run " + std::to_string(**run_id) + " is not active");
    auto id = station_.abort_run("aborted by operator" + (*reason ? ": " + **reason : std::string()), req);
    if (!id) return std::unexpected(id.error());
    return json{{"run_id", *id}, {"state", "aborted"}};
  }

  if (cmd == "run.resume") {
    auto run_id = opt_int(req, "run_id", 1, kMaxId);
    if (!run_id) return std::unexpected(run_id.error());
    if (!*run_id) return api_error(ErrorCode::bad_request, "run_id: missing");
    const double now = std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
    auto id = station_.resume_run(**run_id, now, req);
    if (!id) return std::unexpected(id.error());
    return json{{"run_id", *id}, {"state", "interrupted"}, {"resumes", "at the next tick"}};
  }

  if (cmd == "run.list") {
    storage::RunFilter f;
    auto state = opt_string(req, "state");
    if (!state) return std::unexpected(state.error());
    if (*state) {
      f.state = storage::run_state_from_string(**state);
      if (!f.state) return api_error(ErrorCode::bad_request, "state: not a run state");
    }
    auto purpose = opt_string(req, "purpose");
    if (!purpose) return std::unexpected(purpose.error());
    if (*purpose) {
      f.purpose = storage::purpose_from_string(**purpose);
      if (!f.purpose) return api_error(ErrorCode::bad_request, "purpose: expected \"fit\" or \"verify\"");
    }
    auto serial = opt_string(req, "serial");
    if (!serial) return std::unexpected(serial.error());
    f.serial = *serial;
    auto profile = opt_string(req, "profile");
    if (!profile) return std::unexpected(profile.error());
    f.profile_name = *profile;
    auto limit = opt_int(req, "limit", 1, 10000);
    if (!limit) return std::unexpected(limit.error());
    f.limit = limit->value_or(100);
    auto offset = opt_int(req, "offset", 0, kMaxId);
    if (!offset) return std::unexpected(offset.error());
    f.offset = offset->value_or(0);
    auto runs = store.list_runs(f);
    if (!runs) return std::unexpected(store_error(runs.error()));
    json arr = json::array();
    for (const auto& r : *runs) {
      json j = run_json(r);
      // As in run.get: an end the store has not taken yet is the run's state all the same (a
      // run so ended no longer matches a filter on its stored state).
      if (json end = station_.unrecorded_end(r.id); !end.is_null()) {
        if (f.state && end["state"] != std::string(storage::to_string(*f.state))) continue;
        j["state"] = end["state"];
        j["reason"] = end["reason"];
        j["recorded"] = false;
      }
      arr.push_back(std::move(j));
    }
    return json{{"runs", arr}};
  }

  if (cmd == "run.get") {
    auto run_id = req_int(req, "run_id", 1, kMaxId);
    if (!run_id) return std::unexpected(run_id.error());
    auto d = store.get_run(*run_id);
    if (!d) return std::unexpected(store_error(d.error()));
    json r = run_json(d->run);
    // An end the store could not take yet (a full disk) is the run's state all the same.
    if (json end = station_.unrecorded_end(*run_id); !end.is_null()) {
      r["state"] = end["state"];
      r["reason"] = end["reason"];
      r["recorded"] = false;
    }
    json events = json::array();
    // Data quality per unit: live while the run is active, else the `quality` note stored when
    // it ended (null for a run without one: interrupted by a crash, imported, older).
    json quality = station_.live_quality(*run_id);
    const bool live = !quality.is_null();
    for (const auto& e : d->events) {
      json detail = parse_or_string(e.detail_json);
      if (!live && e.kind == storage::EventKind::note && detail.is_object() && detail.contains("quality"))
        quality = detail["quality"];
      events.push_back({{"id", e.id}, {"t_s", e.t_s ? json(*e.t_s) : json(nullptr)}, {"at", e.at},
                        {"kind", std::string(storage::to_string(e.kind))}, {"detail", std::move(detail)}});
    }
    json models = json::array();
    for (const auto& u : d->run.units) {
      auto ms = store.list_models(u.serial);
      if (!ms) return std::unexpected(store_error(ms.error()));
      for (const auto& m : *ms)
        if (m.run_id == *run_id)
          models.push_back({{"id", m.id}, {"serial", m.serial}, {"version", m.version},
                            {"unit", u.unit_index}, {"terms", m.terms}, {"method", m.method},
                            {"parent_id", m.parent_id ? json(*m.parent_id) : json(nullptr)}});
    }
    auto vs = store.list_verifications(*run_id);
    if (!vs) return std::unexpected(store_error(vs.error()));
    json vers = json::array();
    for (const auto& v : *vs)
      vers.push_back({{"id", v.id}, {"unit", v.unit_index}, {"model_id", v.model_id},
                      {"pass", v.pass}, {"result", parse_or_string(v.result_json)}});
    json samples = json::array();
    for (const auto& u : d->run.units) {
      auto n = store.count_samples(*run_id, u.unit_index);
      samples.push_back(n ? *n : 0);
    }
    return json{{"run", r}, {"samples", samples}, {"quality", quality}, {"events", events}, {"models", models},
                {"verifications", vers}, {"config", parse_or_string(d->run.config_json)},
                {"profile_text", d->run.profile_text}};
  }

  if (cmd == "run.samples") {
    auto run_id = req_int(req, "run_id", 1, kMaxId);
    if (!run_id) return std::unexpected(run_id.error());
    auto offset = opt_int(req, "offset", 0, kMaxId);
    if (!offset) return std::unexpected(offset.error());
    auto limit = opt_int(req, "limit", 1, 10000);
    if (!limit) return std::unexpected(limit.error());
    auto unit = resolve_unit(store, *run_id, req);
    if (!unit) return std::unexpected(unit.error());
    auto total = store.count_samples(*run_id, *unit);
    if (!total) return std::unexpected(store_error(total.error()));
    auto rows = store.get_samples(*run_id, *unit, offset->value_or(0), limit->value_or(1000));
    if (!rows) return std::unexpected(store_error(rows.error()));
    json arr = json::array();
    for (const auto& r : *rows) arr.push_back(sample_json(r));
    return json{{"run_id", *run_id}, {"unit", *unit}, {"offset", offset->value_or(0)},
                {"total", *total}, {"samples", arr}};
  }

  if (cmd == "profile.list") {
    json arr = json::array();
    for (const auto& name : station_.profile_names()) {
      auto p = station_.load_profile(name);
      json e = {{"name", name}};
      if (p) {
        e["valid"] = true;
        e["nominal_duration_s"] = p->nominal_duration_s();
        e["steps"] = p->steps.size();
      } else {
        e["valid"] = false;
        e["error"] = {{"code", std::string(to_string(p.error().code))}, {"message", p.error().message}};
      }
      arr.push_back(e);
    }
    return json{{"profiles", arr}};
  }

  if (cmd == "profile.validate") {
    auto text = opt_string(req, "text");
    if (!text) return std::unexpected(text.error());
    auto name = opt_string(req, "name");
    if (!name) return std::unexpected(name.error());
    if (!!*text == !!*name) return api_error(ErrorCode::bad_request, "expected either text or name");
    auto p = *text ? station_.check_profile_text(**text, "<text>") : station_.load_profile(**name);
    if (!p) return std::unexpected(p.error());
    return json{{"valid", true}, {"nominal_duration_s", p->nominal_duration_s()}, {"steps", p->steps.size()}};
  }

  if (cmd == "model.get") {
    auto serial = opt_string(req, "serial");
    if (!serial) return std::unexpected(serial.error());
    auto id = opt_int(req, "model_id", 1, kMaxId);
    if (!id) return std::unexpected(id.error());
    if (!!*serial == !!*id) return api_error(ErrorCode::bad_request, "expected either serial or model_id");
    if (*id) {
      auto m = store.get_model(**id);
      if (!m) return std::unexpected(store_error(m.error()));
      return model_json(*m);
    }
    auto m = store.current_model(**serial);
    if (!m) return std::unexpected(store_error(m.error()));
    if (!*m) return api_error(ErrorCode::not_found, "no model for serial " + **serial);
    return model_json(**m);
  }

  if (cmd == "model.fit" || cmd == "model.verify") {
    auto run_id = req_int(req, "run_id", 1, kMaxId);
    if (!run_id) return std::unexpected(run_id.error());
    if (station_.active_run_id() == *run_id)
      return api_error(ErrorCode::busy, "run " + std::to_string(*run_id) + " is still active");
    auto unit = resolve_unit(store, *run_id, req);
    if (!unit) return std::unexpected(unit.error());
    ApiResult<json> r;
    if (cmd == "model.fit") {
      auto terms = opt_string(req, "terms");
      if (!terms) return std::unexpected(terms.error());
      auto method = opt_string(req, "method");
      if (!method) return std::unexpected(method.error());
      r = station_.fit_unit(*run_id, *unit, terms->value_or(""), method->value_or(""));
    } else {
      auto model_id = opt_int(req, "model_id", 1, kMaxId);
      if (!model_id) return std::unexpected(model_id.error());
      r = station_.verify_unit(*run_id, *unit, *model_id);
    }
    if (r) station_.audit(*run_id, req);
    return r;
  }

  // The workbench on stored runs: compare and diagnose read, add_term stores a refined model.
  if (cmd == "model.compare" || cmd == "model.diagnose" || cmd == "model.add_term") {
    auto run_id = req_int(req, "run_id", 1, kMaxId);
    if (!run_id) return std::unexpected(run_id.error());
    if (station_.active_run_id() == *run_id)
      return api_error(ErrorCode::busy, "run " + std::to_string(*run_id) + " is still active");
    auto unit = resolve_unit(store, *run_id, req);
    if (!unit) return std::unexpected(unit.error());
    auto model_id = opt_int(req, "model_id", 1, kMaxId);
    if (!model_id) return std::unexpected(model_id.error());
    if (cmd == "model.compare") return station_.compare_unit(*run_id, *unit, *model_id);
    if (cmd == "model.diagnose") {
      std::vector<std::int64_t> held;
      if (auto it = req.find("held_out"); it != req.end()) {
        if (!it->is_array()) return api_error(ErrorCode::bad_request, "held_out: expected an array of run ids");
        for (std::size_t i = 0; i < it->size(); ++i) {
          const json& v = (*it)[i];
          if (!v.is_number_integer() || v.get<std::int64_t>() < 1)
            return api_error(ErrorCode::bad_request, "held_out[" + std::to_string(i) + "]: expected a run id");
          held.push_back(v.get<std::int64_t>());
        }
      }
      return station_.diagnose_unit(*run_id, *unit, *model_id, held);
    }
    auto term = opt_string(req, "term");
    if (!term) return std::unexpected(term.error());
    if (!*term) return api_error(ErrorCode::bad_request, "term: missing (the term to add, e.g. \"T1\")");
    auto r = station_.add_term_unit(*run_id, *unit, **term, *model_id);
    if (r) station_.audit(*run_id, req);
    return r;
  }

  return api_error(ErrorCode::unknown_command, "unknown command: " + cmd);
}

}  // namespace fogbench::daemon
