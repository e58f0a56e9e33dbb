// fogctl plan ... and fogctl queue ...: the plan file read here and sent as text (the daemon
// parses and checks it, so its errors name the file's lines), progress of --wait from
// plan.status, and the plan's HTML report.
#include "plan.hpp"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <thread>

#include "client_commands.hpp"
#include "common.hpp"
#include "html.hpp"
#include "fogbench/plans/plan.hpp"

namespace fogbench::cli {

using nlohmann::json;
using namespace commands;

namespace {

// The plan file: a path, or the name of a shipped plan (shipped_dirs("plans"): $FOGBENCH_PLAN_DIR,
// <prefix>/share/fogbench/plans).
std::expected<std::pair<std::string, std::string>, std::string> read_plan(const std::string& name) {
  auto found = find_shipped("plans", name, ".plan");
  if (!found) return std::unexpected(found.error());
  const std::filesystem::path path = *found;
  std::ifstream in(path);
  if (!in) return std::unexpected("plan '" + path.string() + "': cannot be read");
  std::stringstream ss;
  ss << in.rdbuf();
  return std::make_pair(ss.str(), path.filename().string());
}

// `plan validate --offline`: the plan checked as the daemon checks it, without one: its
// language and limits (plans::parse_plan), and each step's profile as this fogctl finds it
// (shipped_dirs("profiles")), parsed. The reply has the daemon's shape, with "checked":
// "offline". Units, models and the daemon's own profile directory are not checked.
std::expected<json, int> validate_offline(const std::string& name) {
  auto text = read_plan(name);
  if (!text) {
    std::cerr << "fogctl: " << text.error() << "\n";
    return std::unexpected(kExitError);
  }
  auto plan = plans::parse_plan(text->first, text->second);
  if (!plan) {
    std::cerr << "fogctl: " << plan.error().to_string() << "\n" << plan.error().excerpt() << "\n";
    return std::unexpected(kExitError);
  }
  json steps = json::array(), limits = json::array();
  double total_s = 0.0;
  for (const auto& step : plan->steps) {
    auto profile = load_profile(step.profile);
    if (!profile) {
      std::cerr << "fogctl: " << text->second << ":" << step.line << ": step '" << step.profile << "': " << profile.error() << "\n";
      return std::unexpected(kExitError);
    }
    const double nominal_s = profile->nominal_duration_s();
    total_s += nominal_s;
    steps.push_back({{"line", step.line}, {"profile", step.profile}, {"purpose", plans::to_string(step.purpose)},
                     {"nominal_duration_s", nominal_s}});
  }
  for (const auto& l : plan->limits)
    limits.push_back({{"line", l.line}, {"limit", l.describe()}, {"on_fail", plans::to_string(l.on_fail)}});
  return json{{"name", plan->name}, {"steps", std::move(steps)}, {"limits", std::move(limits)},
              {"nominal_duration_s", total_s}, {"checked", "offline"}};
}

std::string cell_text(const json& v) { return v.is_string() ? v.get<std::string>() : v.is_null() ? "-" : v.dump(); }
// A measurement's name, with its axis for a three-axis unit's ("comp_raw (y)"); a one-axis unit's as it is.
std::string plan_measurement_label(const json& m) {
  return cell_text(m["measurement"]) + (m.contains("axis") ? " (" + cell_text(m["axis"]) + ")" : std::string());
}

// A plan's operator ("-" when nobody was recorded) and its units' lots ("SIM-0001=L7 ...", "-").
std::string operator_text(const json& p) {
  const std::string name = p.value("operator", "");
  return name.empty() ? "-" : name;
}
std::string lots_text(const json& p) {
  std::string t;
  if (p.contains("lots") && p["lots"].is_object())
    for (const auto& [serial, lot] : p["lots"].items()) t += (t.empty() ? "" : " ") + serial + "=" + cell_text(lot);
  return t.empty() ? "-" : t;
}

void print_status(const json& s, std::ostream& out) {
  out << "plan " << s["plan_id"] << " " << cell_text(s["name"]) << " (" << cell_text(s["source"]) << "): " << cell_text(s["state"]);
  if (!s["reason"].get<std::string>().empty()) out << ": " << cell_text(s["reason"]);
  out << "\n";
  out << "operator " << operator_text(s) << ", lots " << lots_text(s) << "\n";
  const json& p = s["progress"];
  if (p.is_object() && p.contains("runs")) {
    Table runs({"step", "profile", "purpose", "attempt", "run", "units"});
    for (const auto& r : p["runs"]) {
      std::string units;
      for (const auto& u : r["units"]) units += (units.empty() ? "" : " ") + u.get<std::string>();
      runs.add({cell_text(r["step"]), cell_text(r["profile"]), cell_text(r["purpose"]),
                std::to_string(r["attempt"].get<int>() + 1), cell_text(r["run_id"]), units});
    }
    out << "\n" << runs.str();
    Table units({"serial", "verdict", "measurement", "step", "value", "limit", "met", "on fail"});
    for (const auto& u : p["units"]) {
      bool first = true;
      const std::string verdict = u["verdict"].is_null() ? (u["active"].get<bool>() ? "running" : "-") : cell_text(u["verdict"]);
      for (const auto& m : u["measurements"]) {
        units.add({first ? cell_text(u["serial"]) : "", first ? verdict : "", plan_measurement_label(m), cell_text(m["step"]),
                   m["value"].is_number() ? num_text(m["value"], 4) : "-", cell_text(m["limit"]),
                   m["met"].get<bool>() ? "yes" : "NO", cell_text(m["on_fail"])});
        first = false;
      }
      if (first) units.add({cell_text(u["serial"]), verdict, "-", "-", "-", "-", "-", "-"});
    }
    out << "\n" << units.str();
    for (const auto& u : p["units"])
      for (const auto& r : u["reasons"]) out << cell_text(u["serial"]) << ": " << r.get<std::string>() << "\n";
  }
}

// One progress line per change on err until the plan ends; the final status.
std::expected<json, ClientError> follow(const Common& o, std::int64_t id, bool quiet, std::ostream& err) {
  std::string last;
  auto deadline_reconnect = std::chrono::steady_clock::now() + std::chrono::seconds(300);
  for (;;) {
    auto c = open(o);
    if (!c) {
      if (std::chrono::steady_clock::now() > deadline_reconnect) return std::unexpected(c.error());
      std::this_thread::sleep_for(std::chrono::seconds(1));
      continue;
    }
    for (;;) {
      auto r = c->call("plan.status", {{"plan_id", id}});
      if (!r) break;  // the daemon went away: reconnect (a restart resumes the plan)
      deadline_reconnect = std::chrono::steady_clock::now() + std::chrono::seconds(300);
      const json& s = *r;
      const std::string state = s["state"];
      if (state != "running" && state != "queued") return s;
      if (!quiet) {
        const json& p = s["progress"];
        std::ostringstream line;
        if (state == "queued") line << "plan " << id << " queued";
        else {
          line << "plan " << id << " step " << (p.value("step", 0) + 1) << "/" << p.value("steps", 0);
          if (p.value("attempt", 0) > 0) line << " (retest)";
          if (p["run_id"].is_number()) line << " run " << p["run_id"];
          if (!s.contains("run") || !s["run"].is_object()) line << " waiting for the " << cell_text(p["waiting"]);
          if (s.contains("run") && s["run"].is_object()) {
            const json& run = s["run"];
            line << " " << cell_text(run.value("state", json("?")));
            if (run.contains("elapsed_s")) line << " " << duration_text(run["elapsed_s"].get<double>());
            if (run.contains("remaining_s") && run["remaining_s"].is_number())
              line << ", " << duration_text(run["remaining_s"].get<double>()) << " left in the step";
          }
        }
        if (line.str() != last) {
          err << line.str() << "\n";
          last = line.str();
        }
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(500));
    }
  }
}

}  // namespace

int plan_exit_code(const json& s) {
  if (s.value("state", "") != "completed") return kExitError;
  bool fail = false, marginal = false;
  for (const auto& u : s["progress"]["units"]) {
    fail = fail || u["verdict"] == "fail";
    marginal = marginal || u["verdict"] == "marginal";
  }
  return fail ? kExitFailed : marginal ? kExitMarginal : kExitOk;
}

// For each unit, the command that reports its runs of the plan (model, Table 1, plots) from
// the daemon: `fogctl report --unit SERIAL --run 1 --run 2 -o report-SERIAL.html`, with the unit's current model when
// the plan fitted one, else with a model file to give (`--model MODEL.json`).
static std::string report_commands_html(const json& progress) {
  std::string items;
  for (const auto& u : progress["units"]) {
    const std::string serial = cell_text(u["serial"]);
    std::string runs;
    bool fitted = false;
    for (const auto& r : progress["runs"]) {
      if (!r["run_id"].is_number_integer()) continue;
      bool has = false;
      for (const auto& x : r["units"]) has = has || (x.is_string() && x.get<std::string>() == serial);
      if (!has) continue;
      runs += " --run " + std::to_string(r["run_id"].get<std::int64_t>());
      fitted = fitted || (r["purpose"].is_string() && r["purpose"].get<std::string>() == "fit");
    }
    if (runs.empty()) continue;
    // The output file named: report refuses to run without one (exit 2).
    items += "<li><code>" + html_escape("fogctl report " + std::string(fitted ? "" : "--model MODEL.json ") + "--unit " + serial + runs +
                                        " -o report-" + serial + ".html") +
             "</code>" + (fitted ? "" : " (the plan fitted no model of this unit: give one)") + "</li>";
  }
  if (items.empty()) return "<p>No run of the plan has been stored yet: no report to make.</p>\n";
  return "<p>Each unit's report of its runs (the model, Table 1, the plots), through the daemon's socket "
         "(<code>--socket</code> or <code>--connect</code> as for any fogctl command):</p><ul>" + items + "</ul>\n";
}

std::string plan_report_html(const json& s) {
  std::ostringstream h;
  const json& p = s["progress"];
  h << "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>plan " << s["plan_id"] << " "
    << html_escape(cell_text(s["name"])) << "</title>\n<style>body{font-family:sans-serif;margin:2em}table{border-collapse:collapse;"
    << "margin:1em 0}td,th{border:1px solid #bbb;padding:3px 8px;text-align:left}.pass{background:#dfd}"
    << ".marginal{background:#ffd}.fail,.no{background:#fdd}pre{background:#f6f6f6;padding:1em}</style></head><body>\n";
  h << "<h1>Qualification plan " << s["plan_id"] << ": " << html_escape(cell_text(s["name"])) << "</h1>\n";
  h << "<p>Source " << html_escape(cell_text(s["source"])) << ", state <b>" << html_escape(cell_text(s["state"])) << "</b>"
    << (s["reason"].get<std::string>().empty() ? "" : ": " + html_escape(s["reason"].get<std::string>())) << ". Started "
    << html_escape(cell_text(s["started_at"])) << ", ended " << html_escape(cell_text(s["ended_at"])) << ".</p>\n";
  h << "<p>Operator " << html_escape(operator_text(s)) << ", lots " << html_escape(lots_text(s)) << ".</p>\n";
  h << "<h2>Verdicts</h2>\n<table><tr><th>serial</th><th>verdict</th><th>why</th></tr>\n";
  for (const auto& u : p["units"]) {
    const std::string v = cell_text(u["verdict"]);
    std::string why;
    for (const auto& r : u["reasons"]) why += html_escape(r.get<std::string>()) + "<br>";
    h << "<tr class=\"" << html_escape(v) << "\"><td>" << html_escape(cell_text(u["serial"])) << "</td><td>" << html_escape(v) << "</td><td>"
      << why << "</td></tr>\n";
  }
  h << "</table>\n<h2>Steps and runs</h2>\n<table><tr><th>step</th><th>profile</th><th>purpose</th><th>attempt</th>"
    << "<th>run</th><th>units</th></tr>\n";
  for (const auto& r : p["runs"]) {
    std::string units;
    for (const auto& u : r["units"]) units += (units.empty() ? "" : ", ") + u.get<std::string>();
    h << "<tr><td>" << r["step"] << "</td><td>" << html_escape(cell_text(r["profile"])) << "</td><td>" << html_escape(cell_text(r["purpose"]))
      << "</td><td>" << (r["attempt"].get<int>() + 1) << "</td><td>" << r["run_id"] << "</td><td>" << html_escape(units)
      << "</td></tr>\n";
  }
  h << "</table>\n<h2>Measurements against the limits</h2>\n<table><tr><th>serial</th><th>step</th><th>run</th>"
    << "<th>measurement</th><th>value</th><th>limit</th><th>met</th><th>on fail</th><th>note</th></tr>\n";
  for (const auto& u : p["units"])
    for (const auto& m : u["measurements"]) {
      const bool met = m["met"].get<bool>();
      h << "<tr class=\"" << (met ? "" : "no") << "\"><td>" << html_escape(cell_text(u["serial"])) << "</td><td>" << m["step"]
        << "</td><td>" << m["run_id"] << "</td><td>" << html_escape(plan_measurement_label(m)) << "</td><td>"
        << (m["value"].is_number() ? num_text(m["value"], 4) + " " + html_escape(cell_text(m["unit"])) : "not measured")
        << "</td><td>" << html_escape(cell_text(m["limit"])) << " (line " << m["line"] << ")</td><td>" << (met ? "yes" : "no")
        << "</td><td>" << html_escape(cell_text(m["on_fail"])) << "</td><td>" << html_escape(m.value("note", "")) << "</td></tr>\n";
    }
  h << "</table>\n<h2>The plan</h2>\n<pre>" << html_escape(cell_text(s["plan_text"])) << "</pre>\n";
  h << report_commands_html(p);
  h << "</body></html>\n";
  return h.str();
}

void add_plan_commands(CLI::App& app, int& code) {
  static Common common;
  static std::string file, reason, output, operator_name;
  static std::vector<std::string> units, lots, slots;
  static bool wait = false, quiet = false, offline = false;
  static std::int64_t plan_id = 0, position = 0;
  static std::optional<std::int64_t> status_id;

  auto* plan = app.add_subcommand("plan", "Qualification plans on fogbenchd: validate, start, follow, abort, report");
  plan->require_subcommand(1);

  // send_plan and simple are copied into the callbacks that use them: they outlive this function.
  auto send_plan = [&](const std::string& cmd, bool need_units) -> std::expected<json, int> {
    auto text = read_plan(file);
    if (!text) {
      std::cerr << "fogctl: " << text.error() << "\n";
      return std::unexpected(kExitError);
    }
    auto c = open(common);
    if (!c) {
      const int rc = report(c.error(), std::cerr);
      if (cmd == "plan.validate")
        std::cerr << "hint: without a daemon, `fogctl plan validate --offline " << file
                  << "` checks the plan's language, limits and profiles\n";
      return std::unexpected(rc);
    }
    json args = {{"text", text->first}, {"source", text->second}};
    std::string what = "fogctl " + cmd;  // "fogctl plan start"
    std::replace(what.begin(), what.end(), '.', ' ');
    if ((need_units || !units.empty() || !slots.empty()) && !add_units_and_slots(args, units, slots, what, std::cerr))
      return std::unexpected(kExitError);
    if (need_units && !add_operator_and_lots(args, operator_name, lots, what, std::cerr))
      return std::unexpected(kExitError);
    auto r = c->call(cmd, args);
    if (!r) return std::unexpected(report(r.error(), std::cerr));
    return *r;
  };

  auto* validate = plan->add_subcommand("validate", "Check a plan file against the daemon's profiles (and units, models)");
  add_common(validate, common);
  validate->add_option("plan", file, "Plan file, or the name of a shipped plan (paper, qualification)")->required();
  validate->add_option("--unit", units, "Serial of a unit (repeatable): also checks it is configured and has a model "
                                        "where a verify step needs one");
  validate->add_option("--slot", slots, "SLOT=SERIAL: a unit in a bench slot (repeatable), checked as --unit is");
  validate->add_flag("--offline", offline,
                     "Check without a daemon: the plan's language, its limits and its profiles as this fogctl finds them "
                     "($FOGBENCH_PROFILE_DIR, the shipped ones); units and models are not checked");
  validate->callback([&, send_plan] {
    auto r = offline ? validate_offline(file) : send_plan("plan.validate", false);
    if (!r) {
      code = r.error();
      return;
    }
    if (common.json_out) std::cout << r->dump() << "\n";
    else {
      std::cout << "plan " << cell_text((*r)["name"]) << ": valid, " << (*r)["steps"].size() << " steps, nominally "
                << duration_text((*r)["nominal_duration_s"].get<double>())
                << (offline ? " (checked offline: this fogctl's profiles; units, models and the daemon's profiles not checked)" : "")
                << "\n";
      Table t({"line", "profile", "purpose", "nominal"});
      for (const auto& s : (*r)["steps"])
        t.add({cell_text(s["line"]), cell_text(s["profile"]), cell_text(s["purpose"]),
               duration_text(s["nominal_duration_s"].get<double>())});
      std::cout << t.str();
      Table l({"line", "limit", "on fail"});
      for (const auto& s : (*r)["limits"]) l.add({cell_text(s["line"]), cell_text(s["limit"]), cell_text(s["on_fail"])});
      if (!(*r)["limits"].empty()) std::cout << l.str();
    }
    code = kExitOk;
  });

  auto* start = plan->add_subcommand("start", "Start a plan on units; --wait follows it to the end and exits with the verdict");
  add_common(start, common);
  start->add_option("plan", file, "Plan file, or the name of a shipped plan (paper, qualification)")->required();
  start->add_option("--slot", slots,
                    "SLOT=SERIAL: the serial of the unit in that bench slot, e.g. A=FOG-0042, for every run of the plan (repeatable)");
  start->add_option("--unit", units, "Serial of a unit under test that is a slot's configured serial (repeatable)");
  start->add_option("--operator", operator_name,
                    "Who runs it, recorded in every run of the plan (default: the unix socket's user)");
  start->add_option("--lot", lots, "The units' production lot: LOT for every unit, or SERIAL=LOT (repeatable)");
  start->add_flag("--wait", wait, "Follow the plan with a progress line on stderr until it ends; exit 0 all pass, "
                                  "3 marginal, 1 a unit failed, 2 the plan did not complete");
  start->add_flag("-q,--quiet", quiet, "With --wait: no progress line");
  start->callback([&, send_plan] {
    auto r = send_plan("plan.start", true);
    if (!r) {
      code = r.error();
      return;
    }
    const auto id = (*r)["plan_id"].get<std::int64_t>();
    if (!wait) {
      if (common.json_out) std::cout << r->dump() << "\n";
      else std::cout << "plan " << id << " started\n";
      code = kExitOk;
      return;
    }
    if (!common.json_out) std::cerr << "plan " << id << " started\n";
    auto s = follow(common, id, quiet, std::cerr);
    if (!s) {
      code = report(s.error(), std::cerr);
      return;
    }
    if (common.json_out) std::cout << s->dump() << "\n";
    else print_status(*s, std::cout);
    code = plan_exit_code(*s);
  });

  auto* status = plan->add_subcommand("status", "Show a plan (the running one, else the last) with every measurement");
  add_common(status, common);
  status->add_option("id", status_id, "Plan id");
  status->callback([&] {
    auto c = open(common);
    if (!c) {
      code = report(c.error(), std::cerr);
      return;
    }
    json args = json::object();
    if (status_id) args["plan_id"] = *status_id;
    auto r = c->call("plan.status", args);
    if (!r) {
      code = report(r.error(), std::cerr);
      return;
    }
    if (common.json_out) std::cout << r->dump() << "\n";
    else print_status(*r, std::cout);
    code = kExitOk;
  });

  auto* abort = plan->add_subcommand("abort", "Abort the running plan and its run; the chamber goes to its safe setpoint");
  add_common(abort, common);
  abort->add_option("--reason", reason, "Why, for the audit trail");
  abort->callback([&] {
    auto c = open(common);
    if (!c) {
      code = report(c.error(), std::cerr);
      return;
    }
    auto r = c->call("plan.abort", {{"reason", reason}});
    if (!r) {
      code = report(r.error(), std::cerr);
      return;
    }
    if (common.json_out) std::cout << r->dump() << "\n";
    else std::cout << "plan " << (*r)["plan_id"] << " aborted\n";
    code = kExitOk;
  });

  auto* rep = plan->add_subcommand("report", "One HTML report for a whole plan: verdicts, runs, measurements vs limits");
  add_common(rep, common, false);
  rep->add_option("id", plan_id, "Plan id")->required();
  rep->add_option("-o,--output", output, "HTML file to write (default plan-ID.html)");
  rep->callback([&] {
    auto c = open(common);
    if (!c) {
      code = report(c.error(), std::cerr);
      return;
    }
    auto r = c->call("plan.status", {{"plan_id", plan_id}});
    if (!r) {
      code = report(r.error(), std::cerr);
      return;
    }
    const std::string path = output.empty() ? "plan-" + std::to_string(plan_id) + ".html" : output;
    if (auto ok = write_text(path, plan_report_html(*r)); !ok) {
      std::cerr << "fogctl: " << ok.error() << "\n";
      code = kExitError;
      return;
    }
    std::cout << "wrote " << path << "\n";
    code = kExitOk;
  });

  auto* queue = app.add_subcommand("queue", "The plans waiting for the chamber: list, add, remove, move");
  queue->require_subcommand(1);
  auto simple = [&](const std::string& cmd, json args, const std::string& said) {
    auto c = open(common);
    if (!c) {
      code = report(c.error(), std::cerr);
      return;
    }
    auto r = c->call(cmd, std::move(args));
    if (!r) {
      code = report(r.error(), std::cerr);
      return;
    }
    if (common.json_out) std::cout << r->dump() << "\n";
    else std::cout << said << "\n";
    code = kExitOk;
  };
  auto* list = queue->add_subcommand("list", "The queued plans in the order they will run");
  add_common(list, common);
  list->callback([&] {
    auto c = open(common);
    if (!c) {
      code = report(c.error(), std::cerr);
      return;
    }
    auto r = c->call("queue.list");
    if (!r) {
      code = report(r.error(), std::cerr);
      return;
    }
    if (common.json_out) std::cout << r->dump() << "\n";
    else {
      std::cout << "running: " << ((*r)["running"].is_null() ? "no plan" : "plan " + (*r)["running"].dump()) << "\n";
      Table t({"#", "plan", "name", "source", "units", "operator", "lots", "queued at"});
      for (const auto& q : (*r)["queue"]) {
        std::string us;
        for (const auto& u : q["units"]) us += (us.empty() ? "" : " ") + u.get<std::string>();
        t.add({cell_text(q["position"]), cell_text(q["plan_id"]), cell_text(q["name"]), cell_text(q["source"]), us,
               operator_text(q), lots_text(q), cell_text(q["created_at"])});
      }
      std::cout << t.str();
    }
    code = kExitOk;
  });
  auto* add = queue->add_subcommand("add", "Queue a plan on units; it starts when the chamber is free");
  add_common(add, common);
  add->add_option("plan", file, "Plan file, or the name of a shipped plan")->required();
  add->add_option("--slot", slots,
                    "SLOT=SERIAL: the serial of the unit in that bench slot, e.g. A=FOG-0042, for every run of the plan (repeatable)");
  add->add_option("--unit", units, "Serial of a unit under test that is a slot's configured serial (repeatable)");
  add->add_option("--operator", operator_name,
                  "Who runs it, recorded in every run of the plan (default: the unix socket's user when queued)");
  add->add_option("--lot", lots, "The units' production lot: LOT for every unit, or SERIAL=LOT (repeatable)");
  add->callback([&, send_plan] {
    auto r = send_plan("queue.add", true);
    if (!r) {
      code = r.error();
      return;
    }
    if (common.json_out) std::cout << r->dump() << "\n";
    else std::cout << "plan " << (*r)["plan_id"] << " queued at position " << (*r)["position"] << "\n";
    code = kExitOk;
  });
  auto* remove = queue->add_subcommand("remove", "Take a queued plan out of the queue (a running one: plan abort)");
  add_common(remove, common);
  remove->add_option("id", plan_id, "Plan id")->required();
  remove->callback([&, simple] { simple("queue.remove", {{"plan_id", plan_id}}, "plan " + std::to_string(plan_id) + " removed from the queue"); });
  auto* move = queue->add_subcommand("move", "Move a queued plan to a position (1: next)");
  add_common(move, common);
  move->add_option("id", plan_id, "Plan id")->required();
  move->add_option("position", position, "New position, 1 = next")->required();
  move->callback([&, simple] {
    simple("queue.move", {{"plan_id", plan_id}, {"position", position}},
           "plan " + std::to_string(plan_id) + " moved to position " + std::to_string(position));
  });
}

}  // namespace fogbench::cli
