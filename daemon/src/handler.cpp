// The command handler: request validation with messages that name the field, and one function
// per command. Every failure is an error reply; nothing here throws to the caller.
#include "fogbench/daemon/handler.hpp"
#include "fogbench/daemon/plan_runner.hpp"

#include <algorithm>
#include <array>
#include <cassert>
#include <chrono>
#include <cmath>

#include "fogbench/daemon/analysis.hpp"
#include "fogbench/daemon/certificate.hpp"
#include "fogbench/daemon/run_identity.hpp"
#include "run_reads.hpp"
#include "fogbench/storage/identity.hpp"
#include "fogbench/protocol/framing.hpp"
#include "fogbench/model/json.hpp"

namespace fogbench::daemon {

using nlohmann::json;

namespace {

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
// model.diagnose's held_out runs (docs/protocol.md): the paper's method holds out two.
constexpr std::size_t kMaxHeldOutRuns = 32;

}  // namespace

namespace {
// In time independent of where the strings differ, so a remote client cannot find the token
// byte by byte from reply times.
bool same_token(const std::string& a, const std::string& b) {
  unsigned diff = a.size() == b.size() ? 0u : 1u;
  for (std::size_t i = 0; i < b.size(); ++i) diff |= static_cast<unsigned char>(i < a.size() ? a[i] : 0) ^ static_cast<unsigned char>(b[i]);
  return diff == 0;
}


// What a job on the worker threw: a bug, reported as `internal`, never a dead thread.
template <class T, class F>
ApiResult<T> guarded(F&& f) {
  try {
    return f();
  } catch (const std::exception& e) {
    return api_error(ErrorCode::internal, e.what());
  }
}

// What a command's handler is given: the request without its token, and its connection.
struct CommandCall {
  Handler& handler;
  const std::string& cmd;
  const json& req;
  SessionState& session;
};

}  // namespace

// The handlers of the command table, one per command. Those that answer on the loop return
// the result; the offloaded ones check their arguments here and submit the rest to the
// station's Offload, replying through `done` (at once when an argument is refused).
struct CommandHandlers {
  using OnLoop = ApiResult<json> (*)(const CommandCall&);
  using Offloaded = void (*)(const CommandCall&, const json& id, Handler::Done);

  static Station& station(const CommandCall& c) { return c.handler.station_; }
  static void fail(const json& id, const Handler::Done& done, const ApiError& e) {
    done(Handler::to_line(Handler::error(id, e.code, e.message)));
  }

  // ---- on the loop ----

  static ApiResult<json> status(const CommandCall& c) { return station(c).status(); }

  static ApiResult<json> subscribe(const CommandCall& c) {
    c.session.subscribed = true;
    return json{{"subscribed", true}};
  }
  static ApiResult<json> unsubscribe(const CommandCall& c) {
    c.session.subscribed = false;
    return json{{"subscribed", false}};
  }

  // Whether the store issued a certificate of this hash (fogctl cert --check).
  static ApiResult<json> cert_check(const CommandCall& c) {
    auto hash = req_string(c.req, "sha256");
    if (!hash) return std::unexpected(hash.error());
    auto found = station(c).store().find_certificates(*hash);
    if (!found) return std::unexpected(from_store(found.error()));
    json certs = json::array();
    for (const auto& cert : *found)
      certs.push_back({{"id", cert.id}, {"serial", cert.serial}, {"model_version", cert.model_version},
                       {"created_at", cert.created_at}});
    return json{{"known", !found->empty()}, {"certificates", certs}};
  }

  // The configuration file read again (docs/daemon.md "Reloading the configuration"): what
  // applied and what needs a restart, or invalid_config with nothing changed.
  static ApiResult<json> config_reload(const CommandCall& c) { return station(c).reload(); }

  // The station's public key (fogctl cert --public-key): what a customer checks certificates
  // with, offline (docs/daemon.md "The station key").
  static ApiResult<json> cert_public_key(const CommandCall& c) {
    Station& st = station(c);
    const auto& key = st.signing_key();
    const auto& path = st.signing_key_path();
    return json{{"algorithm", "ed25519"},
                {"key_id", key.key_id()},
                {"station_id", st.config().station_id},
                {"public_key_pem", key.public_key().pem()},
                {"key_path", path.empty() ? json(nullptr) : json(path.string())},
                {"public_key_path", path.empty() ? json(nullptr) : json(signing::public_path_of(path).string())}};
  }

  static ApiResult<json> run_start(const CommandCall& c) {
    const json& req = c.req;
    auto profile = req_string(req, "profile");
    if (!profile) return std::unexpected(profile.error());
    if (auto why = storage::check_stored_text("profile", *profile, storage::kMaxNameBytes); !why.empty())
      return api_error(ErrorCode::bad_request, why);
    auto units = slot_units(req, station(c).config().drivers.units, true);  // bench_slots.hpp
    if (!units) return std::unexpected(units.error());
    auto purpose_text = opt_string(req, "purpose");
    if (!purpose_text) return std::unexpected(purpose_text.error());
    const auto purpose = storage::purpose_from_string(purpose_text->value_or("fit"));
    if (!purpose) return api_error(ErrorCode::bad_request, "purpose: expected \"fit\" or \"verify\"");
    auto op = operator_of(req, c.session.peer_user);
    if (!op) return std::unexpected(op.error());
    auto id = station(c).start_run_in_slots(*profile, *units, *purpose, req, *op);
    if (!id) return std::unexpected(id.error());
    return json{{"run_id", *id}, {"state", "pending"}};
  }

  static ApiResult<json> run_abort(const CommandCall& c) {
    auto reason = opt_string(c.req, "reason");
    if (!reason) return std::unexpected(reason.error());
    if (*reason)
      if (auto why = storage::check_stored_text("reason", **reason, storage::kMaxReasonBytes); !why.empty())
        return api_error(ErrorCode::bad_request, why);
    auto run_id = opt_int(c.req, "run_id", 1, kMaxId);
    if (!run_id) return std::unexpected(run_id.error());
    auto active = station(c).active_run_id();
    if (*run_id && active != *run_id)
      return api_error(ErrorCode::not_found, "run " + std::to_string(**run_id) + " is not active");
    auto id = station(c).abort_run("aborted by operator" + (*reason ? ": " + **reason : std::string()), c.req);
    if (!id) return std::unexpected(id.error());
    return json{{"run_id", *id}, {"state", "aborted"}};
  }

  // Offloaded: the replay of the run's stored seconds runs on the worker (Station::
  // resume_run_async), the run is taken up back on the loop, then the reply.
  static void run_resume(const CommandCall& c, const json& id, Handler::Done done) {
    auto run_id = opt_int(c.req, "run_id", 1, kMaxId);
    if (!run_id) return fail(id, done, run_id.error());
    if (!*run_id) return fail(id, done, ApiError{ErrorCode::bad_request, "run_id: missing"});
    const double now = std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
    station(c).resume_run_async(**run_id, now, c.req, origin_of(c), [id, done](ApiResult<std::int64_t> r) {
      done(Handler::to_line(r ? Handler::reply(id, json{{"run_id", *r}, {"state", "interrupted"}, {"resumes", "at the next tick"}})
                              : Handler::error(id, r.error().code, r.error().message)));
    });
  }

  static ApiResult<json> run_list(const CommandCall& c) {
    const json& req = c.req;
    Station& st = station(c);
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
    auto runs = st.store().list_runs(f);
    if (!runs) return std::unexpected(from_store(runs.error()));
    json arr = json::array();
    for (const auto& r : *runs) {
      json j = run_json(r);
      // As in run.get: an end the store has not taken yet is the run's state all the same (a
      // run so ended no longer matches a filter on its stored state).
      if (json end = st.unrecorded_end(r.id); !end.is_null()) {
        if (f.state && end["state"] != std::string(storage::to_string(*f.state))) continue;
        j["state"] = end["state"];
        j["reason"] = end["reason"];
        j["recorded"] = false;
      }
      arr.push_back(std::move(j));
    }
    return json{{"runs", arr}};
  }

  static ApiResult<json> profile_list(const CommandCall& c) {
    Station& st = station(c);
    json arr = json::array();
    for (const auto& name : st.profile_names()) {
      auto p = st.load_profile(name, nullptr);
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

  static ApiResult<json> profile_validate(const CommandCall& c) {
    auto text = opt_string(c.req, "text");
    if (!text) return std::unexpected(text.error());
    auto name = opt_string(c.req, "name");
    if (!name) return std::unexpected(name.error());
    if (!!*text == !!*name) return api_error(ErrorCode::bad_request, "expected either text or name");
    auto p = *text ? station(c).check_profile_text(**text, "<text>") : station(c).load_profile(**name, nullptr);
    if (!p) return std::unexpected(p.error());
    return json{{"valid", true}, {"nominal_duration_s", p->nominal_duration_s()}, {"steps", p->steps.size()}};
  }

  static ApiResult<json> model_get(const CommandCall& c) {
    storage::Store& store = station(c).store();
    auto serial = opt_string(c.req, "serial");
    if (!serial) return std::unexpected(serial.error());
    auto id = opt_int(c.req, "model_id", 1, kMaxId);
    if (!id) return std::unexpected(id.error());
    if (!!*serial == !!*id) return api_error(ErrorCode::bad_request, "expected either serial or model_id");
    if (*id) {
      auto m = store.get_model(**id);
      if (!m) return std::unexpected(from_store(m.error()));
      return model_json(*m);
    }
    auto m = store.current_model(**serial);
    if (!m) return std::unexpected(from_store(m.error()));
    if (!*m) return api_error(ErrorCode::not_found, "no model for serial " + **serial);
    json out = model_json(**m);
    // A three-axis unit's serial (one with a y or z model): the reply is x's, and `axes` each
    // axis' current model; a one-axis unit's reply has no `axes`.
    json axes = json::array();
    bool three = false;
    for (const char* axis : {"x", "y", "z"}) {
      auto a = store.current_model(**serial, axis);
      if (!a) return std::unexpected(from_store(a.error()));
      if (!*a) {
        axes.push_back({{"axis", axis}, {"id", nullptr}});
        continue;
      }
      three = three || (*a)->axis == "y" || (*a)->axis == "z";
      axes.push_back({{"axis", axis}, {"id", (*a)->id}, {"version", (*a)->version}, {"method", (*a)->method},
                      {"terms", (*a)->terms}, {"run_id", (*a)->run_id ? json(*(*a)->run_id) : json(nullptr)}});
    }
    if (three) out["axes"] = std::move(axes);
    return out;
  }

  // plan.* and queue.*: arguments checked and the work done in plan_commands.cpp.
  template <PlanCommand F>
  static ApiResult<json> plan(const CommandCall& c) {
    return F(station(c).plan_runner(), c.cmd, c.req);
  }
  template <PlanStartCommand F>
  static ApiResult<json> plan_as_peer(const CommandCall& c) {
    return F(station(c).plan_runner(), c.cmd, c.req, c.session.peer_user);
  }

  // ---- offloaded ----

  // Who asks (offload.hpp, JobClass): the unix socket is the local operator; a network client
  // is served after it, and has at most socket.max_analyses_per_address jobs waiting or running
  // from its address, so a few pipelining clients cannot hold up the station's work or each
  // other's.
  static JobOrigin origin_of(const CommandCall& c) {
    if (c.session.may_control) return {JobClass::local, {}};
    return {JobClass::remote, c.session.address.empty() ? std::string("(unknown address)") : c.session.address};
  }
  static std::expected<JobOrigin, ApiError> admit_job(const CommandCall& c) {
    JobOrigin o = origin_of(c);
    if (o.job_class != JobClass::remote) return o;
    const auto limit = static_cast<std::size_t>(station(c).config().socket.max_analyses_per_address);
    const auto waiting = station(c).offload().pending_from(o.address);
    if (waiting >= limit)
      return std::unexpected(ApiError{ErrorCode::busy, "too many analysis requests from " + o.address + " (" +
                                                           std::to_string(waiting) +
                                                           " waiting or running, socket.max_analyses_per_address); "
                                                           "send it again once one is answered"});
    return o;
  }

  // A read: the whole reply built and serialised on the worker (10,000 samples are megabytes).
  static void read(const CommandCall& c, const json& id, Handler::Done done,
                   std::function<ApiResult<json>(storage::Store&)> compute) {
    auto origin = admit_job(c);
    if (!origin) return fail(id, done, origin.error());
    station(c).offload().submit([id, compute = std::move(compute), done](storage::Store& reader) -> Offload::Then {
      ApiResult<json> r = guarded<json>([&] { return compute(reader); });
      Handler::Line line = Handler::to_line(r ? Handler::reply(id, std::move(*r)) : Handler::error(id, r.error().code, r.error().message));
      return [done, line] { done(line); };
    }, std::move(*origin));
  }

  // An analysis: computed on the worker, what it produced stored here on the loop (its Commit),
  // and the command audited when it succeeded (the control ones: model.fit, model.verify,
  // model.add_term).
  static void analyse(const CommandCall& c, const json& id, Handler::Done done, std::int64_t run_id, bool audit,
                      std::function<ApiResult<analysis::Commit>(storage::Store&)> compute) {
    auto origin = admit_job(c);
    if (!origin) return fail(id, done, origin.error());
    Station* st = &station(c);
    st->offload().submit([st, id, run_id, audit, req = c.req, compute = std::move(compute), done](storage::Store& reader) -> Offload::Then {
      auto commit = std::make_shared<ApiResult<analysis::Commit>>(guarded<analysis::Commit>([&] { return compute(reader); }));
      return [st, id, run_id, audit, req, commit, done] {
        ApiResult<json> r = !*commit ? ApiResult<json>(std::unexpected((*commit).error()))
                            // The run was resumed meanwhile: nothing is stored against a live run.
                            : audit && st->active_run_id() == run_id
                                ? ApiResult<json>(api_error(ErrorCode::busy, "run " + std::to_string(run_id) + " is active again"))
                                : guarded<json>([&] { return (**commit)(st->store()); });
        if (r && audit) st->audit(run_id, req);
        done(Handler::to_line(r ? Handler::reply(id, std::move(*r)) : Handler::error(id, r.error().code, r.error().message)));
      };
    }, std::move(*origin));
  }

  // The run an analysis is asked of: not the run being recorded.
  static ApiResult<std::int64_t> analysed_run(const CommandCall& c) {
    auto run_id = req_int(c.req, "run_id", 1, kMaxId);
    if (!run_id) return std::unexpected(run_id.error());
    if (station(c).active_run_id() == *run_id)
      return api_error(ErrorCode::busy, "run " + std::to_string(*run_id) + " is still active");
    return *run_id;
  }

  static void run_get(const CommandCall& c, const json& id, Handler::Done done) {
    auto run_id = req_int(c.req, "run_id", 1, kMaxId);
    if (!run_id) return fail(id, done, run_id.error());
    const std::int64_t rid = *run_id;
    // What the station knows that the store may not have taken yet, as of now.
    json end = station(c).unrecorded_end(rid), quality = station(c).live_quality(rid);
    read(c, id, std::move(done), [rid, end, quality](storage::Store& s) { return daemon::run_get(s, rid, end, quality); });
  }

  static void run_samples(const CommandCall& c, const json& id, Handler::Done done) {
    auto run_id = req_int(c.req, "run_id", 1, kMaxId);
    if (!run_id) return fail(id, done, run_id.error());
    auto offset = opt_int(c.req, "offset", 0, kMaxId);
    if (!offset) return fail(id, done, offset.error());
    auto limit = opt_int(c.req, "limit", 1, 10000);
    if (!limit) return fail(id, done, limit.error());
    read(c, id, std::move(done), [rid = *run_id, req = c.req, off = offset->value_or(0), lim = limit->value_or(1000)](storage::Store& s) {
      return daemon::run_samples(s, rid, req, off, lim);
    });
  }

  // cert.get: the certificate built on the worker from its read connection, then handed out on
  // the loop: the serial's stored one when nothing changed, else a new one stored (certificate.hpp).
  static void cert_get(const CommandCall& c, const json& id, Handler::Done done) {
    auto serial = req_string(c.req, "serial");
    if (!serial) return fail(id, done, serial.error());
    auto origin = admit_job(c);
    if (!origin) return fail(id, done, origin.error());
    Station* st = &station(c);
    st->offload().submit([st, id, s = *serial, limits = st->config().analysis,
                          station_id = st->config().station_id, done](storage::Store& reader) -> Offload::Then {
      auto body = std::make_shared<ApiResult<json>>(guarded<json>([&] { return certificate::build(reader, limits, station_id, s); }));
      return [st, id, body, done] {
        ApiResult<json> r = !*body ? ApiResult<json>(std::unexpected(body->error())) : guarded<json>([&]() -> ApiResult<json> {
          auto cert = certificate::issue(st->store(), **body, st->wall_now(), st->signing_key());
          if (!cert) return std::unexpected(cert.error());
          return json{{"certificate", cert->first}, {"issued_now", cert->second}};
        });
        done(Handler::to_line(r ? Handler::reply(id, std::move(*r)) : Handler::error(id, r.error().code, r.error().message)));
      };
    }, std::move(*origin));
  }

  static void model_fit(const CommandCall& c, const json& id, Handler::Done done) {
    auto run_id = analysed_run(c);
    if (!run_id) return fail(id, done, run_id.error());
    auto terms = opt_string(c.req, "terms");
    if (!terms) return fail(id, done, terms.error());
    auto method = opt_string(c.req, "method");
    if (!method) return fail(id, done, method.error());
    analyse(c, id, std::move(done), *run_id, true,
            [rid = *run_id, req = c.req, t = terms->value_or(""), m = method->value_or(""),
             config = station(c).config().analysis, at = station(c).wall_now()](storage::Store& s) -> ApiResult<analysis::Commit> {
              auto unit = resolve_unit(s, rid, req);
              if (!unit) return std::unexpected(unit.error());
              return analysis::fit(s, config, rid, *unit, t, m, at);
            });
  }

  static void model_verify(const CommandCall& c, const json& id, Handler::Done done) {
    auto run_id = analysed_run(c);
    if (!run_id) return fail(id, done, run_id.error());
    auto model_id = opt_int(c.req, "model_id", 1, kMaxId);
    if (!model_id) return fail(id, done, model_id.error());
    analyse(c, id, std::move(done), *run_id, true,
            [rid = *run_id, req = c.req, mid = *model_id, config = station(c).config().analysis](storage::Store& s)
                -> ApiResult<analysis::Commit> {
              auto unit = resolve_unit(s, rid, req);
              if (!unit) return std::unexpected(unit.error());
              return analysis::verify(s, config, rid, *unit, mid);
            });
  }

  static void model_compare(const CommandCall& c, const json& id, Handler::Done done) {
    auto run_id = analysed_run(c);
    if (!run_id) return fail(id, done, run_id.error());
    auto model_id = opt_int(c.req, "model_id", 1, kMaxId);
    if (!model_id) return fail(id, done, model_id.error());
    analyse(c, id, std::move(done), *run_id, false,
            [rid = *run_id, req = c.req, mid = *model_id](storage::Store& s) -> ApiResult<analysis::Commit> {
              auto unit = resolve_unit(s, rid, req);
              if (!unit) return std::unexpected(unit.error());
              return analysis::compare(s, rid, *unit, mid);
            });
  }

  static void model_diagnose(const CommandCall& c, const json& id, Handler::Done done) {
    auto run_id = analysed_run(c);
    if (!run_id) return fail(id, done, run_id.error());
    const std::int64_t rid = *run_id;
    auto model_id = opt_int(c.req, "model_id", 1, kMaxId);
    if (!model_id) return fail(id, done, model_id.error());
    std::vector<std::int64_t> held;
    if (auto it = c.req.find("held_out"); it != c.req.end()) {
      if (!it->is_array()) return fail(id, done, {ErrorCode::bad_request, "held_out: expected an array of run ids"});
      for (std::size_t i = 0; i < it->size(); ++i) {
        const json& v = (*it)[i];
        if (!v.is_number_integer() || v.get<std::int64_t>() < 1)
          return fail(id, done, {ErrorCode::bad_request, "held_out[" + std::to_string(i) + "]: expected a run id"});
        const std::int64_t other = v.get<std::int64_t>();
        const std::string at = "held_out[" + std::to_string(i) + "]: run " + std::to_string(other);
        // Held out means not fitted on: the model's own run would score as its own witness,
        // and a run twice would count twice in the held-out figures.
        if (other == rid) return fail(id, done, {ErrorCode::bad_request, at + " is the run diagnosed, not a held-out one"});
        if (std::find(held.begin(), held.end(), other) != held.end())
          return fail(id, done, {ErrorCode::bad_request, at + " is listed twice"});
        if (station(c).active_run_id() == other) return fail(id, done, {ErrorCode::busy, at + " is still active"});
        held.push_back(other);
      }
      // Each held-out run is read and scored for every candidate on the one analysis worker.
      if (held.size() > kMaxHeldOutRuns)
        return fail(id, done, {ErrorCode::bad_request, "held_out: at most " + std::to_string(kMaxHeldOutRuns) + " runs, got " +
                                                           std::to_string(held.size())});
    }
    analyse(c, id, std::move(done), rid, false,
            [rid, req = c.req, mid = *model_id, held](storage::Store& s) -> ApiResult<analysis::Commit> {
              auto unit = resolve_unit(s, rid, req);
              if (!unit) return std::unexpected(unit.error());
              return analysis::diagnose(s, rid, *unit, mid, held);
            });
  }

  static void model_add_term(const CommandCall& c, const json& id, Handler::Done done) {
    auto run_id = analysed_run(c);
    if (!run_id) return fail(id, done, run_id.error());
    auto model_id = opt_int(c.req, "model_id", 1, kMaxId);
    if (!model_id) return fail(id, done, model_id.error());
    auto term = opt_string(c.req, "term");
    if (!term) return fail(id, done, term.error());
    if (!*term) return fail(id, done, {ErrorCode::bad_request, "term: missing (the term to add, e.g. \"T1\")"});
    analyse(c, id, std::move(done), *run_id, true,
            [rid = *run_id, req = c.req, mid = *model_id, t = **term, at = station(c).wall_now()](storage::Store& s)
                -> ApiResult<analysis::Commit> {
              auto unit = resolve_unit(s, rid, req);
              if (!unit) return std::unexpected(unit.error());
              return analysis::add_term(s, rid, *unit, t, mid, at);
            });
  }
};

namespace {

// One entry of the command table: its name, its access and its handler, whose kind (on the loop
// or offloaded) is the entry's `offloaded`. Every field is required.
struct CommandEntry {
  CommandInfo info;
  CommandHandlers::OnLoop on_loop = nullptr;
  CommandHandlers::Offloaded offloaded = nullptr;
  constexpr CommandEntry(std::string_view name, Access access, CommandHandlers::OnLoop f)
      : info{name, access, false}, on_loop(f) {}
  constexpr CommandEntry(std::string_view name, Access access, CommandHandlers::Offloaded f)
      : info{name, access, true}, offloaded(f) {}
};


// Every socket command of the protocol (docs/protocol.md; what a new one touches:
// docs/adding-a-command.md). `control`: changes something (a run, a model, a plan, the queue),
// so on a connection that may only read it needs the token.
constexpr CommandEntry kCommands[] = {
    {"status", Access::read, &CommandHandlers::status},
    {"subscribe", Access::read, &CommandHandlers::subscribe},
    {"unsubscribe", Access::read, &CommandHandlers::unsubscribe},
    {"run.start", Access::control, &CommandHandlers::run_start},
    {"run.abort", Access::control, &CommandHandlers::run_abort},
    {"run.resume", Access::control, &CommandHandlers::run_resume},
    {"run.list", Access::read, &CommandHandlers::run_list},
    {"run.get", Access::read, &CommandHandlers::run_get},
    {"run.samples", Access::read, &CommandHandlers::run_samples},
    {"profile.list", Access::read, &CommandHandlers::profile_list},
    {"profile.validate", Access::read, &CommandHandlers::profile_validate},
    {"model.get", Access::read, &CommandHandlers::model_get},
    {"model.fit", Access::control, &CommandHandlers::model_fit},
    {"model.verify", Access::control, &CommandHandlers::model_verify},
    {"model.compare", Access::read, &CommandHandlers::model_compare},
    {"model.diagnose", Access::read, &CommandHandlers::model_diagnose},
    {"model.add_term", Access::control, &CommandHandlers::model_add_term},
    // Stores the certificate it issues, but changes no measurement.
    {"cert.get", Access::read, &CommandHandlers::cert_get},
    {"cert.check", Access::read, &CommandHandlers::cert_check},
    {"cert.public_key", Access::read, &CommandHandlers::cert_public_key},
    {"plan.validate", Access::read, &CommandHandlers::plan<plan_validate>},
    {"plan.start", Access::control, &CommandHandlers::plan_as_peer<plan_start>},
    {"plan.status", Access::read, &CommandHandlers::plan<plan_status>},
    {"plan.abort", Access::control, &CommandHandlers::plan<plan_abort>},
    {"queue.list", Access::read, &CommandHandlers::plan<queue_list>},
    {"queue.add", Access::control, &CommandHandlers::plan_as_peer<queue_add>},
    {"queue.remove", Access::control, &CommandHandlers::plan<queue_remove>},
    {"queue.move", Access::control, &CommandHandlers::plan<queue_move>},
    {"config.reload", Access::control, &CommandHandlers::config_reload},
};

constexpr bool table_is_sound() {
  for (std::size_t i = 0; i < std::size(kCommands); ++i) {
    const CommandEntry& c = kCommands[i];
    if (c.info.name.empty() || (c.on_loop == nullptr) == (c.offloaded == nullptr)) return false;
    for (std::size_t j = i + 1; j < std::size(kCommands); ++j)
      if (kCommands[j].info.name == c.info.name) return false;
  }
  return true;
}
static_assert(table_is_sound(), "a command without a name or a handler, or one listed twice");

constexpr auto kInfos = [] {
  std::array<CommandInfo, std::size(kCommands)> infos{};
  for (std::size_t i = 0; i < infos.size(); ++i) infos[i] = kCommands[i].info;
  return infos;
}();

const CommandEntry* find_entry(std::string_view name) {
  for (const CommandEntry& c : kCommands)
    if (c.info.name == name) return &c;
  return nullptr;
}

}  // namespace

std::span<const CommandInfo> commands() { return kInfos; }

const CommandInfo* find_command(std::string_view name) {
  const CommandEntry* c = find_entry(name);
  return c ? &kInfos[static_cast<std::size_t>(c - std::begin(kCommands))] : nullptr;
}

bool is_control_command(std::string_view cmd) {
  const CommandInfo* c = find_command(cmd);
  return c && c->access == Access::control;
}

bool Handler::offloaded(std::string_view cmd) {
  const CommandInfo* c = find_command(cmd);
  return c && c->offloaded;
}

json Handler::hello() {
  return protocol::to_json(protocol::Hello{FOGBENCH_DAEMON_VERSION});
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
               "line longer than " + std::to_string(protocol::kMaxLineBytes) + " bytes; closing");
}

Handler::Line Handler::to_line(const json& message) {
  return std::make_shared<const std::string>(message.dump(-1, ' ', false, json::error_handler_t::replace) + "\n");
}

namespace {
// The reply of a call through the asynchronous path when the Offload runs inline.
template <class Call>
json sync_reply(Call&& call) {
  Handler::Line out;
  call([&out](Handler::Line l) { out = std::move(l); });
  assert(out && "Handler's synchronous calls need an Offload that runs inline");
  if (!out) return Handler::error(nullptr, ErrorCode::internal, "no reply (the analysis runs on a worker)");
  return json::parse(*out);
}
}  // namespace

json Handler::handle_line(std::string_view line, SessionState& session) {
  return sync_reply([&](Done d) { handle_line(line, session, std::move(d)); });
}

json Handler::handle(const json& req, SessionState& session) {
  return sync_reply([&](Done d) { handle(req, session, std::move(d)); });
}

void Handler::handle_line(std::string_view line, SessionState& session, Done done) {
  // The protocol's limits are checked while parsing, before any of the value exists: a request
  // nested past kMaxDepth or with a key twice is refused here (protocol/framing.hpp's parse_line).
  auto req = protocol::parse_line(line);
  if (!req) return done(to_line(error(nullptr, ErrorCode::bad_json, req.error())));
  handle(*req, session, std::move(done));
}

void Handler::handle(const json& req, SessionState& session, Done done) {
  auto fail = [&](const json& id, ErrorCode code, const std::string& message) {
    done(to_line(error(id, code, message)));
  };
  if (!req.is_object()) return fail(nullptr, ErrorCode::bad_request, "expected a JSON object");
  json id = req.contains("id") ? req["id"] : json(nullptr);
  if (!id.is_null() && !id.is_number_integer() && !id.is_string())
    return fail(nullptr, ErrorCode::bad_request, "id: expected an integer or a string");
  if (id.is_null()) return fail(nullptr, ErrorCode::bad_request, "id: missing");
  if (!req.contains("cmd")) return fail(id, ErrorCode::bad_request, "cmd: missing");
  if (!req["cmd"].is_string()) return fail(id, ErrorCode::bad_request, "cmd: expected a string");
  const std::string cmd = req["cmd"].get<std::string>();
  // The token is a credential: checked here and never stored with the command in the audit trail.
  json request = req;
  json token = request.contains("token") ? request["token"] : json(nullptr);
  request.erase("token");
  if (!token.is_null() && !token.is_string()) return fail(id, ErrorCode::bad_request, "token: expected a string");
  const CommandEntry* command = find_entry(cmd);
  if (!command) return fail(id, ErrorCode::unknown_command, "unknown command: " + cmd);
  if (!session.may_control && command->info.access == Access::control) {
    if (session.control_token.empty())
      return fail(id, ErrorCode::forbidden, cmd + ": only on the local socket; this connection may only read");
    if (token.is_null() || !same_token(token.get<std::string>(), session.control_token))
      return fail(id, ErrorCode::forbidden, cmd + ": needs a valid token on this connection");
  }
  const CommandCall call{*this, cmd, request, session};
  json out;
  try {
    if (command->offloaded) return command->offloaded(call, id, done);
    auto r = command->on_loop(call);
    out = r ? reply(id, std::move(*r)) : error(id, r.error().code, r.error().message);
  } catch (const std::exception& e) {
    // A bug, not an input: reported, and the daemon stays up.
    out = error(id, ErrorCode::internal, e.what());
  }
  done(to_line(out));
}

}  // namespace fogbench::daemon
