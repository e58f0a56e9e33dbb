// fogctl's run commands over the daemon client: status; run start, list, get, abort, resume,
// export; model get; and fit/verify --run N, which fetch a stored run into a CSV and hand it to
// the offline command. The watch of a run is in watch.cpp.
#include <cctype>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <sstream>

#include "client_commands.hpp"
#include "run_identity.hpp"
#include "common.hpp"
#include "fogbench/storage/csv.hpp"

namespace fogbench::cli {

namespace commands {

using nlohmann::json;

void add_common(CLI::App* c, Common& o, bool with_json) {
  c->add_option("--socket", o.socket, "fogbenchd's socket (default: $FOGBENCH_SOCKET or /run/fogbench/fogbenchd.sock)");
  c->add_option("--connect", o.connect,
                "HOST:PORT: talk to fogbenchd over TCP (socket.tcp) instead of the unix socket; reads need "
                "nothing, control commands need --token");
  c->add_option("--token", o.token,
                "The daemon's socket.tcp.token, for control commands over TCP (default: $FOGBENCH_TOKEN; the "
                "variable keeps it out of the process list)");
  if (with_json) c->add_flag("--json", o.json_out, "Print JSON for machines");
}

std::string num_text(const json& v, int digits) {
  return v.is_number() ? fixed(v.get<double>(), digits) : "-";
}
std::string num_text(std::optional<double> v, int digits) {
  return v && std::isfinite(*v) ? fixed(*v, digits) : "-";
}
std::string num_text(double v, int digits) { return num_text(std::optional<double>(v), digits); }

std::string duration_text(double s) {
  if (!std::isfinite(s) || s < 0) return "-";
  const auto t = static_cast<long long>(std::llround(s));
  char buf[32];
  std::snprintf(buf, sizeof buf, "%lld:%02lld:%02lld", t / 3600, (t / 60) % 60, t % 60);
  return buf;
}

int report(const ClientError& e, std::ostream& err) {
  // A reply's error says its code, as the daemon sent it; the client's own failures need none.
  err << "fogctl: " << (e.code == ClientErrc::reply ? e.reply_code_text + ": " : "") << e.message << "\n";
  return kExitError;
}

std::expected<Client, ClientError> open(const Common& o) {
  Endpoint e;
  e.socket_path = o.socket;
  if (!o.connect.empty()) {
    auto tcp = parse_connect(o.connect);
    if (!tcp) return std::unexpected(ClientError{ClientErrc::bad_option, tcp.error(), std::nullopt, {}});
    e = *tcp;
  }
  return Client::connect(e, o.token);
}

// Per unit of a run, what it lost: frames lost and corrupt, samples flagged (`quality` of
// status.run and of run.get). "-" where the daemon has no counts (a run interrupted by a crash).
Table quality_table(const json& serials, const json& quality, const json* samples) {
  std::vector<std::string> head = {"unit", "serial"};
  if (samples) head.push_back("samples");
  for (const char* h : {"frames_lost", "frames_corrupt", "samples_flagged"}) head.push_back(h);
  Table t(head);
  for (std::size_t i = 0; i < serials.size(); ++i) {
    std::vector<std::string> row = {std::to_string(i), serials[i].get<std::string>()};
    if (samples) row.push_back(i < samples->size() ? std::to_string((*samples)[i].get<std::int64_t>()) : "-");
    const json* q = nullptr;
    if (quality.is_array())
      for (const auto& x : quality)
        if (x.value("unit", -1) == static_cast<int>(i)) q = &x;
    for (const char* k : {"frames_lost", "frames_corrupt", "samples_flagged"})
      row.push_back(q && (*q)[k].is_number_integer() ? std::to_string((*q)[k].get<std::int64_t>()) : "-");
    t.add(row);
  }
  return t;
}

// status.plant in one line: the outbox, and the link's state (STALLED in capitals: a transaction
// or connection attempt without progress for plant.stall_s, docs/plant.md "The link's state").
std::string plant_status_text(const json& p) {
  std::ostringstream o;
  o << "plant: bench '" << p.value("bench_id", std::string("?")) << "', outbox " << p.value("outbox_depth", 0)
    << " waiting, " << p.value("sent", 0) << " sent";
  if (p.contains("error") && p["error"].is_string()) o << ", outbox unreadable: " << p["error"].get<std::string>();
  if (p.contains("link") && p["link"].is_string()) {
    const std::string link = p["link"].get<std::string>();
    const bool stalled = p.value("stalled", false);
    o << "; link " << (stalled ? "STALLED" : link);
    if (p.contains("sending_run_id") && p["sending_run_id"].is_number_integer())
      o << (stalled ? " sending run " : " run ") << p["sending_run_id"].get<std::int64_t>();
    if (link != "idle" && link != "stopped" && p.contains("link_busy_s") && p["link_busy_s"].is_number())
      o << " for " << std::fixed << std::setprecision(1) << p["link_busy_s"].get<double>() << " s";
    if (stalled && p.contains("link_quiet_s") && p["link_quiet_s"].is_number())
      o << ", no progress for " << std::fixed << std::setprecision(1) << p["link_quiet_s"].get<double>() << " s";
  }
  if (p.contains("last_error") && p["last_error"].is_string())
    o << "; last error: " << p["last_error"].get<std::string>();
  return o.str();
}

// --- status
int cmd_status(const Common& o, std::ostream& out, std::ostream& err) {
  auto c = open(o);
  if (!c) return report(c.error(), err);
  auto s = c->call("status");
  if (!s) return report(s.error(), err);
  if (o.json_out) {
    out << s->dump() << "\n";
    return kExitOk;
  }
  const json& ch = (*s)["chamber"];
  out << "fogbenchd " << (*s)["version"].get<std::string>() << (s->value("simulated", false) ? " (simulated" : " (hardware")
      << ", time scale " << (*s)["time_scale"].get<double>() << ")\n";
  out << "chamber: " << num_text(ch["chamber_c"]) << " C, setpoint " << num_text(ch["setpoint_c"]) << " C (commanded "
      << num_text((*s)["setpoint_c"]) << " C), link " << ch["link"].get<std::string>()
      << (ch.value("alarm", false) ? ", ALARM" : "") << "\n";
  // One row per bench slot; its unit: the active run's, else the configured default ("-": none).
  Table t({"slot", "unit", "gyro_dph", "frames", "t1_c", "t2_c"});
  for (const auto& u : (*s)["units"])
    t.add({u.value("slot", std::string("-")), u["serial"].is_string() ? u["serial"].get<std::string>() : "-",
           num_text(u["gyro_dph"], 3), std::to_string(u.value("frames", 0)),
           num_text(u["t1_c"]), num_text(u["t2_c"])});
  out << t.str();
  const json& r = (*s)["run"];
  if (r.is_null()) {
    out << "no run active\n";
  } else {
    out << "run " << r["id"] << ": " << r["state"].get<std::string>() << ", " << r["purpose"].get<std::string>()
        << " on " << r["profile"].get<std::string>() << ", phase "
        << (r["phase"].is_string() ? r["phase"].get<std::string>() : "-") << ", elapsed "
        << duration_text(r["elapsed_s"].get<double>()) << ", remaining "
        << (r["remaining_s"].is_number() ? duration_text(r["remaining_s"].get<double>()) : "-") << "\n";
    out << "data quality of the run:\n" << quality_table(r["units"], r.value("quality", json())).str();
  }
  const json& last = s->value("last_run", json());
  if (last.is_object())
    out << "last run " << last["run_id"] << ": " << last["state"].get<std::string>() << " ("
        << last["reason"].get<std::string>() << ")"
        << (last.value("recorded", true) ? "" : "; NOT yet recorded in the store (retried every 10 s)") << "\n";
  if (const json& p = s->value("plant", json()); p.is_object()) out << plant_status_text(p) << "\n";
  return kExitOk;
}

// --- run list / get / abort
std::string opt_str(const json& v) { return v.is_string() ? v.get<std::string>() : "-"; }

int cmd_run_list(const Common& o, const std::string& state, int limit, std::ostream& out, std::ostream& err) {
  auto c = open(o);
  if (!c) return report(c.error(), err);
  json args = {{"limit", limit}};
  if (!state.empty()) args["state"] = state;
  auto r = c->call("run.list", args);
  if (!r) return report(r.error(), err);
  if (o.json_out) {
    out << r->dump() << "\n";
    return kExitOk;
  }
  Table t({"run", "state", "purpose", "profile", "units", "started", "ended", "reason"});
  for (const auto& run : (*r)["runs"]) {
    std::string units;
    for (const auto& u : run["units"]) units += (units.empty() ? "" : ",") + u.get<std::string>();
    t.add({std::to_string(run["id"].get<std::int64_t>()), run["state"], run["purpose"], run["profile"], units,
           opt_str(run["started_at"]), opt_str(run["ended_at"]), run["reason"]});
  }
  out << t.str();
  return kExitOk;
}

namespace {
std::string upper(std::string s) {
  for (char& c : s) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return s;
}
}  // namespace

void print_table1(const json& verifications, const json& run, std::ostream& out) {
  Table t({"unit", "serial", "model", "est_mean", "meas_mean", "est_std", "meas_std", "comp_std", "comp/raw", "checks met"});
  for (const auto& v : verifications) {
    // model::to_json(Verification) puts the whole run's Table 1 at the top level.
    const json& res = v["result"];
    const json& r = res.contains("run") && res["run"].is_object() ? res["run"] : res;
    const int unit = v["unit"].get<int>();
    t.add({std::to_string(unit), run["units"][static_cast<std::size_t>(unit)].get<std::string>(),
           std::to_string(v["model_id"].get<std::int64_t>()), num_text(r["est_mean"]), num_text(r["meas_mean"]),
           num_text(r["est_std"]), num_text(r["meas_std"]), num_text(r["comp_std"]),
           r["ratio"].is_number() ? pct(r["ratio"].get<double>()) : "-",
           v["pass"].get<bool>() ? "yes" : res.value("verdict", "") == "marginal" ? "MARGINAL" : "NO"});
  }
  out << t.str();
}

int cmd_run_get(const Common& o, std::int64_t id, std::ostream& out, std::ostream& err) {
  auto c = open(o);
  if (!c) return report(c.error(), err);
  auto r = c->call("run.get", {{"run_id", id}});
  if (!r) return report(r.error(), err);
  if (o.json_out) {
    out << r->dump() << "\n";
    return kExitOk;
  }
  const json& run = (*r)["run"];
  out << "run " << id << ": " << run["state"].get<std::string>() << " (" << run["reason"].get<std::string>() << ")\n"
      << "  purpose " << run["purpose"].get<std::string>() << ", profile " << run["profile"].get<std::string>()
      << ", time scale " << run["time_scale"] << "\n  created " << run["created_at"].get<std::string>() << ", started "
      << opt_str(run["started_at"]) << ", ended " << opt_str(run["ended_at"]) << "\n";
  if (run.contains("pruned_at") && run["pruned_at"].is_string())
    out << "  samples pruned at " << run["pruned_at"].get<std::string>() << " ("
        << run.value("pruned_samples", std::int64_t{0}) << " deleted by `fogctl store prune`; the plant store keeps them)\n";
  if (!run.value("recorded", true))
    out << "  its end is NOT yet recorded in the store (a full disk?); the daemon retries every 10 s\n";
  // Per unit: the samples stored and what the run lost (frames lost, corrupt, samples flagged).
  out << quality_table(run["units"], r->value("quality", json()), &(*r)["samples"]).str();
  print_identity(r->value("identity", json()), out);
  if (!(*r)["models"].empty()) {
    // A three-axis unit's models name their axis; a run of one-axis units has no axis column.
    bool any_axis = false;
    for (const auto& m : (*r)["models"]) any_axis = any_axis || m.contains("axis");
    std::vector<std::string> head{"model", "serial", "version", "method", "terms", "parent"};
    if (any_axis) head.insert(head.begin() + 2, "axis");
    Table t(head);
    for (const auto& m : (*r)["models"]) {
      std::vector<std::string> row{std::to_string(m["id"].get<std::int64_t>()), m["serial"], std::to_string(m["version"].get<int>()),
                                   m["method"], m["terms"], m["parent_id"].is_null() ? "-" : std::to_string(m["parent_id"].get<std::int64_t>())};
      if (any_axis) row.insert(row.begin() + 2, m.value("axis", std::string("-")));
      t.add(row);
    }
    out << "models fitted on this run:\n" << t.str();
  }
  if (!(*r)["verifications"].empty()) {
    out << "verifications (Table 1, deg/h):\n";
    print_table1((*r)["verifications"], run, out);
  }
  // Each unit's one verdict (issue 24): decided by this run, or by the plan the run is a step of.
  bool any_verdict = false;
  Table vt({"unit", "serial", "verdict", "decided by", "decided at"});
  for (const auto& v : r->value("verdicts", json::array())) {
    if (!v.is_object()) continue;
    any_verdict = true;
    const std::string verdict = v["verdict"].is_string() ? upper(v["verdict"].get<std::string>()) : v.value("pending", std::string("-"));
    vt.add({std::to_string(v.value("unit", 0)), v.value("serial", std::string()), verdict, verdict_by_text(v),
            v.value("decided_at", std::string("-"))});
  }
  if (any_verdict) out << "verdicts:\n" << vt.str();
  // A three-axis unit's verdict is the worst of its axes': each axis' own, with its model.
  for (const auto& v : r->value("verdicts", json::array())) {
    if (!v.is_object() || !v.contains("axes") || !v["axes"].is_array()) continue;
    out << "  unit " << v.value("unit", 0) << " (" << v.value("serial", std::string()) << ") by axis:";
    for (const auto& a : v["axes"])
      out << " " << a.value("axis", std::string("?")) << " " << upper(a.value("verdict", std::string("-"))) << " (model "
          << (a.contains("model_id") ? a["model_id"].dump() : std::string("-")) << ")";
    out << "\n";
    for (const auto& a : v["axes"])
      for (const auto& why : a.value("reasons", json::array()))
        out << "    axis " << a.value("axis", std::string("?")) << ": " << (why.is_string() ? why.get<std::string>() : why.dump()) << "\n";
  }
  out << "events:\n" << events_table((*r)["events"]).str();
  return kExitOk;
}

int cmd_run_abort(const Common& o, const std::string& reason, std::ostream& out, std::ostream& err) {
  auto c = open(o);
  if (!c) return report(c.error(), err);
  json args = json::object();
  if (!reason.empty()) args["reason"] = reason;
  auto r = c->call("run.abort", args);
  if (!r) return report(r.error(), err);
  if (o.json_out) out << r->dump() << "\n";
  else out << "run " << (*r)["run_id"] << " aborted; the chamber returns to its safe setpoint\n";
  return kExitOk;
}

int cmd_run_export(const Common& o, std::int64_t id, const std::string& unit_arg, bool settle, const std::string& output,
                   std::ostream& out, std::ostream& err) {
  auto c = open(o);
  if (!c) return report(c.error(), err);
  auto unit = resolve_unit(*c, id, unit_arg);
  if (!unit) return report(unit.error(), err);
  auto d = fetch_run(*c, id, *unit, settle, Gaps::keep);  // a gap stays empty (docs/csv.md)
  if (!d) return report(d.error(), err);
  // The run's identity as `# key: value` lines above the header (docs/csv.md).
  auto g = c->call("run.get", {{"run_id", id}});
  if (!g) return report(g.error(), err);
  const std::string csv = identity_csv_comments(*g, *unit) + storage::to_csv(*d);
  if (output.empty() || output == "-") {
    out << csv;
    return kExitOk;
  }
  if (auto ok = write_text(output, csv); !ok) {
    err << "fogctl: " << ok.error() << "\n";
    return kExitError;
  }
  if (!o.json_out) err << "run " << id << " unit " << unit_arg << ": " << d->size() << " samples written to " << output << "\n";
  return kExitOk;
}

int cmd_model_get(const Common& o, const std::string& serial, std::int64_t model_id, const std::string& output,
                  std::ostream& out, std::ostream& err) {
  auto c = open(o);
  if (!c) return report(c.error(), err);
  json args = model_id > 0 ? json{{"model_id", model_id}} : json{{"serial", serial}};
  auto m = c->call("model.get", args);
  if (!m) return report(m.error(), err);
  if (!output.empty()) {
    // The model file fogctl verify --model reads.
    if (auto ok = write_text(output, (*m)["model"].dump(2) + "\n"); !ok) {
      err << "fogctl: " << ok.error() << "\n";
      return kExitError;
    }
  }
  if (o.json_out) {
    out << m->dump() << "\n";
  } else {
    out << "model " << (*m)["id"] << " for " << (*m)["serial"].get<std::string>() << ", version " << (*m)["version"]
        << ", fitted on run " << ((*m)["run_id"].is_null() ? std::string("-") : (*m)["run_id"].dump()) << " ("
        << (*m)["method"].get<std::string>() << "): " << (*m)["terms"].get<std::string>()
        << (m->contains("axis") ? ", axis " + (*m)["axis"].get<std::string>() : std::string()) << "\n";
    // A three-axis unit's serial: each axis' current model (the reply above is x's).
    if (m->contains("axes") && (*m)["axes"].is_array()) {
      out << "  by axis:";
      for (const auto& a : (*m)["axes"])
        out << " " << a.value("axis", std::string("?")) << " "
            << (a.contains("id") && !a["id"].is_null() ? "model " + a["id"].dump() : std::string("none"));
      out << "\n";
    }
    const json& mj = (*m)["model"];
    if (mj.contains("mu0_dph")) out << "  mu0 " << num_text(mj["mu0_dph"], 3) << " deg/h";
    if (mj.contains("sigma_a_dph")) out << ", sigma_a " << num_text(mj["sigma_a_dph"], 3) << " deg/h";
    out << "\n";
    if (!output.empty()) out << "  written to " << output << "\n";
  }
  return kExitOk;
}

}  // namespace commands

namespace commands {

bool add_operator_and_lots(nlohmann::json& req, const std::string& operator_name, const std::vector<std::string>& lots,
                           const std::string& what, std::ostream& err) {
  // Checked here too, so that a bad name is refused before anything is sent.
  if (!operator_name.empty()) {
    if (auto why = storage::check_operator_name(operator_name); !why.empty()) {
      err << what << ": " << why << "\n";
      return false;
    }
    req["operator"] = operator_name;
  }
  // --lot LOT (every unit) or --lot SERIAL=LOT (repeatable): the units' lots (issue 14).
  for (const auto& l : lots) {
    const auto eq = l.find('=');
    if (eq == std::string::npos) {
      if (lots.size() > 1 || l.empty()) {
        err << what << ": --lot: expected LOT (every unit) or SERIAL=LOT (repeatable), not '" << l << "'\n";
        return false;
      }
      req["lot"] = l;
    } else {
      req["lots"][l.substr(0, eq)] = l.substr(eq + 1);
    }
  }
  return true;
}

bool add_units_and_slots(nlohmann::json& req, const std::vector<std::string>& units,
                         const std::vector<std::string>& slots, const std::string& what, std::ostream& err) {
  if (units.empty() && slots.empty()) {
    err << what << ": give the units: --slot SLOT=SERIAL (repeatable) or --unit SERIAL (a slot's configured serial)\n";
    return false;
  }
  if (!units.empty()) req["units"] = units;
  for (const auto& s : slots) {
    const auto eq = s.find('=');
    if (eq == std::string::npos || eq == 0) {
      err << what << ": --slot: expected SLOT=SERIAL, e.g. A=FOG-0042, not '" << s << "'\n";
      return false;
    }
    const std::string slot = s.substr(0, eq);
    if (req.contains("slots") && req["slots"].contains(slot)) {
      err << what << ": --slot: slot " << slot << " given twice\n";
      return false;
    }
    req["slots"][slot] = s.substr(eq + 1);  // the daemon checks the serial (empty, control characters, length)
  }
  return true;
}

}  // namespace commands

namespace {

using namespace commands;
using nlohmann::json;

int cmd_run_start(const Common& o, const std::string& profile, const std::vector<std::string>& units,
                  const std::vector<std::string>& slots, const std::vector<std::string>& lots, const std::string& purpose, const std::string& operator_name,
                  bool wait, bool quiet, std::ostream& out, std::ostream& err) {
  json req = {{"profile", profile}, {"purpose", purpose}};
  if (!add_units_and_slots(req, units, slots, "fogctl run start", err)) return kExitError;
  if (!add_operator_and_lots(req, operator_name, lots, "fogctl run start", err)) return kExitError;
  auto c = open(o);
  if (!c) return report(c.error(), err);
  auto r = c->call("run.start", req);
  if (!r) return report(r.error(), err);
  const auto id = (*r)["run_id"].get<std::int64_t>();
  if (!wait) {
    if (o.json_out) out << r->dump() << "\n";
    else out << "run " << id << " started\n";
    return kExitOk;
  }
  if (!o.json_out) err << "run " << id << " started\n";
  return watch(o, id, quiet, 300.0, out, err);
}

// run.resume: an interrupted run (a crash left it) goes on from where its profile clock stood.
int cmd_run_resume(const Common& o, std::int64_t id, bool wait, bool quiet, std::ostream& out, std::ostream& err) {
  auto c = open(o);
  if (!c) return report(c.error(), err);
  auto r = c->call("run.resume", {{"run_id", id}});
  if (!r) return report(r.error(), err);
  if (!wait) {
    if (o.json_out) out << r->dump() << "\n";
    else out << "run " << id << " resumes at the next tick; the time it was away is stored flagged\n";
    return kExitOk;
  }
  if (!o.json_out) err << "run " << id << " resumed\n";
  return watch(o, id, quiet, 300.0, out, err);
}

// fogbenchd reads its configuration file again (config.reload, as SIGHUP does): a table of the
// changed keys, each applied or needing a restart; a broken file is an error naming the key and
// its line (exit 2), and nothing changed.
int cmd_config_reload(const Common& o, std::ostream& out, std::ostream& err) {
  auto c = open(o);
  if (!c) return report(c.error(), err);
  auto r = c->call("config.reload", json::object());
  if (!r) return report(r.error(), err);
  if (o.json_out) {
    out << r->dump() << "\n";
    return kExitOk;
  }
  out << "configuration reloaded from " << printable(r->value("file", std::string("?"))) << "\n";
  if (!r->value("changed", false)) {
    out << "nothing changed\n";
    return kExitOk;
  }
  Table t({"key", "reload", "when"});
  for (const auto& a : (*r)["applied"]) t.add({a.value("key", ""), "applied", a.value("from", "")});
  for (const auto& a : (*r)["needs_restart"]) t.add({a.value("key", ""), "needs a restart (old value kept)", a.value("why", "")});
  out << t.str();
  if (!(*r)["needs_restart"].empty()) {
    out << "needs a restart:";
    for (const auto& a : (*r)["needs_restart"]) out << " " << printable(a.value("key", ""));
    out << "\n";
  }
  if ((*r)["active_run"].is_number())
    out << "run " << (*r)["active_run"] << " goes on with the units and analysis settings it started with\n";
  return kExitOk;
}

}  // namespace

// The subcommand of that name, or null (CLI11 2.1's get_subcommand throws).
CLI::App* find_subcommand(CLI::App& app, const std::string& name) {
  auto subs = app.get_subcommands([&](CLI::App* a) { return a->get_name() == name; });
  return subs.empty() ? nullptr : subs.front();
}

void add_client_commands(CLI::App& app, int& code) {
  static Common common;
  auto* status = app.add_subcommand("status", "Show the daemon, the chamber, the units, the active run with its data quality, and the last run");
  add_common(status, common);
  status->callback([&] { code = cmd_status(common, std::cout, std::cerr); });

  auto* run = app.add_subcommand("run", "Start, follow, list, inspect, abort, resume and export runs on fogbenchd");
  run->require_subcommand(1);

  static std::string profile, purpose = "fit", reason, state, output, operator_name;
  static std::vector<std::string> units, lots, slots;
  static bool wait = false, quiet = false, settle = false;
  static std::int64_t run_id = 0;
  static int limit = 50;
  static std::string unit = "0";
  static bool raw = false;
  static std::optional<std::int64_t> watch_id;

  auto* start = run->add_subcommand("start", "Start a run of a profile on units; --wait follows it to the end");
  add_common(start, common);
  start->add_option("--profile", profile, "Profile name in the daemon's profile directory, e.g. exp1")->required();
  start->add_option("--slot", slots,
                    "SLOT=SERIAL: the serial of the unit in that bench slot for this run, e.g. A=FOG-0042 (repeatable; "
                    "`fogctl status` lists the slots)");
  start->add_option("--unit", units, "Serial of a unit under test that is a slot's configured serial (repeatable)");
  start->add_option("--purpose", purpose, "fit (a model is fitted at the end) or verify (the current model is checked)")
      ->check(CLI::IsMember({"fit", "verify"}));
  start->add_option("--operator", operator_name,
                    "Who runs it, recorded in the run's identity (default: the unix socket's user)");
  start->add_option("--lot", lots, "The units' production lot: LOT for every unit, or SERIAL=LOT (repeatable)");
  start->add_flag("--wait", wait, "Follow the run with a progress line on stderr until it ends");
  start->add_flag("-q,--quiet", quiet, "With --wait: no progress line");
  start->callback([&] { code = cmd_run_start(common, profile, units, slots, lots, purpose, operator_name, wait, quiet, std::cout, std::cerr); });

  auto* w = run->add_subcommand("watch", "Follow a run (the active one by default) to its end; reconnects if the daemon restarts");
  add_common(w, common);
  w->add_option("run", watch_id, "Run id (default: the active run)");
  w->add_flag("-q,--quiet", quiet, "No progress line");
  w->add_flag("--raw", raw, "Print the run's sample and event messages as they come, one JSON object a line (NDJSON)");
  w->callback([&] { code = watch(common, watch_id, quiet, 300.0, std::cout, std::cerr, raw); });

  auto* list = run->add_subcommand("list", "List runs, newest first");
  add_common(list, common);
  list->add_option("--state", state, "Only runs in this state");
  list->add_option("--limit", limit, "At most this many runs");
  list->callback([&] { code = cmd_run_list(common, state, limit, std::cout, std::cerr); });

  auto* get = run->add_subcommand("get", "Show a run: per unit its samples, frames lost and corrupt, samples flagged; models, verifications, audit trail");
  add_common(get, common);
  get->add_option("run", run_id, "Run id")->required();
  get->callback([&] { code = cmd_run_get(common, run_id, std::cout, std::cerr); });

  auto* abort = run->add_subcommand("abort", "Abort the active run; the chamber returns to its safe setpoint");
  add_common(abort, common);
  abort->add_option("--reason", reason, "Why, for the audit trail");
  abort->callback([&] { code = cmd_run_abort(common, reason, std::cout, std::cerr); });

  static bool resume_wait = false;
  auto* resume = run->add_subcommand(
      "resume", "Take up an interrupted run (one a crash of fogbenchd left) where its profile clock stood");
  add_common(resume, common);
  resume->add_option("run", run_id, "Id of the interrupted run")->required();
  resume->add_flag("--wait", resume_wait, "Follow the run with a progress line on stderr until it ends");
  resume->add_flag("-q,--quiet", quiet, "With --wait: no progress line");
  resume->callback([&] { code = cmd_run_resume(common, run_id, resume_wait, quiet, std::cout, std::cerr); });

  auto* exp = run->add_subcommand("export", "Write a stored run's unit as CSV (the format fogctl fit reads)");
  add_common(exp, common);
  exp->add_option("run", run_id, "Run id")->required();
  exp->add_option("--unit", unit, "The unit, by serial or by index in the run (default 0, the first)");
  exp->add_option("-o,--output", output, "CSV file (default: standard output)");
  exp->add_flag("--include-settle", settle, "Keep the samples of the opening settle");
  exp->callback([&] { code = cmd_run_export(common, run_id, unit, settle, output, std::cout, std::cerr); });

  static std::string model_serial, model_output;
  static std::int64_t model_id = 0;
  auto* models = app.add_subcommand("model", "Models stored by fogbenchd");
  models->require_subcommand(1);
  auto* mget = models->add_subcommand("get", "Show a unit's current model (or one by --id); -o writes its JSON file");
  add_common(mget, common);
  mget->add_option("serial", model_serial, "The unit's serial");
  mget->add_option("--id", model_id, "A model by its id instead");
  mget->add_option("-o,--output", model_output, "Write the model's JSON here (the file fogctl verify --model reads)");
  mget->callback([&] {
    if (model_serial.empty() && model_id <= 0) {
      std::cerr << "fogctl model get: give a serial or --id\n";
      code = kExitError;
      return;
    }
    code = cmd_model_get(common, model_serial, model_id, model_output, std::cout, std::cerr);
  });

  auto* config = app.add_subcommand("config", "fogbenchd's configuration");
  config->require_subcommand(1);
  auto* reload = config->add_subcommand(
      "reload", "Make fogbenchd read its configuration file again (as systemctl reload): apply what can change "
                "without touching the active run, name what needs a restart; a broken file changes nothing (exit 2)");
  add_common(reload, common);
  reload->callback([&] { code = cmd_config_reload(common, std::cout, std::cerr); });
}

}  // namespace fogbench::cli
