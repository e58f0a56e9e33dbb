// fogctl run watch (and run start/resume --wait): follows a run's `sample` and `event` messages
// with a progress line, reconnects when the daemon restarts, and ends with the run's summary and
// exit code.
#include <chrono>
#include <iostream>
#include <map>
#include <sstream>
#include <thread>

#include "client_commands.hpp"
#include "common.hpp"
#include "fogbench/protocol/protocol.hpp"
#include "progress.hpp"

namespace fogbench::cli::commands {

using nlohmann::json;
using SteadyClock = std::chrono::steady_clock;

// The exit code of a finished run: 0 completed (and every verification passed), 3 marginal, 1 a
// verification failed, 2 anything else.
int final_code(Client& c, std::int64_t run_id, std::ostream& out, bool json_out) {
  auto r = c.call("run.get", {{"run_id", run_id}});
  if (!r) return report(r.error(), std::cerr);
  const json& run = (*r)["run"];
  if (json_out) out << r->dump() << "\n";
  else out << "run " << run_id << " " << run["state"].get<std::string>() << ": " << run["reason"].get<std::string>() << "\n";
  if (run["state"] != "completed") return kExitError;
  bool all_pass = true, any_fail = false;
  for (const auto& v : (*r)["verifications"]) {
    all_pass = all_pass && v.value("pass", false);
    // marginal (issue 10): the paper's ratio passed, the second test did not (exit 3)
    const bool marginal = v.contains("result") && v["result"].is_object() && v["result"].value("verdict", "") == "marginal";
    any_fail = any_fail || (!v.value("pass", false) && !marginal);
  }
  if (!json_out) {
    for (const auto& m : (*r)["models"])
      out << "model " << m["id"] << " for " << m["serial"].get<std::string>() << " (version " << m["version"]
          << "): " << m["terms"].get<std::string>() << "\n";
    if (!(*r)["verifications"].empty()) print_table1((*r)["verifications"], run, out);
    for (const auto& e : (*r)["events"])
      if (e["kind"] == "note" && e["detail"].value("ok", true) == false)
        out << "analysis of unit " << e["detail"]["unit"] << " failed: " << e["detail"].value("error", "") << "\n";
  }
  return all_pass ? kExitOk : any_fail ? kExitFailed : kExitMarginal;
}

bool terminal(const std::string& s) {
  return s == "completed" || s == "aborted" || s == "failed" || s == "interrupted";
}

// Follows a run until it ends, reconnecting (every second, up to reconnect_s) when the daemon
// goes away. Progress on `err`, unless quiet.
int watch(const Common& o, std::optional<std::int64_t> run_id, bool quiet, double reconnect_s, std::ostream& out,
          std::ostream& err, bool raw) {
  const bool tty_line = !quiet && !raw;
  // Redrawn on a terminal; in a file one line per phase change and one a minute (progress.hpp).
  Progress progress(err, progress_redraws());
  progress.set_width(progress_width());
  // --raw: the sample and event messages of the run on `out`, one JSON object a line (NDJSON,
  // as gpspipe -w prints gpsd's), and no summary: the exit code still says how the run ended.
  std::ostringstream no_summary;
  std::ostream& summary = raw ? no_summary : out;
  auto lost_since = SteadyClock::now();
  bool warned = false;
  for (;;) {
    auto c = open(o);
    if (!c && c.error().code == ClientErrc::bad_option) return report(c.error(), err);
    if (!c) {
      if (std::chrono::duration<double>(SteadyClock::now() - lost_since).count() > reconnect_s)
        return report(c.error(), err);
      if (!warned) progress.line("fogctl: " + c.error().message + "; retrying");
      warned = true;
      std::this_thread::sleep_for(std::chrono::seconds(1));
      continue;
    }
    warned = false;
    // Subscribe first, then look at the state: nothing can end unseen in between.
    if (auto s = c->call("subscribe"); !s) return report(s.error(), err);
    auto st = c->call("status");
    if (!st) return report(st.error(), err);
    const json& active = (*st)["run"];
    if (!run_id) {
      if (active.is_null()) {
        err << "fogctl: no run is active\n";
        return kExitError;
      }
      run_id = active["id"].get<std::int64_t>();
    }
    if (active.is_null() || active["id"] != *run_id) {
      auto g = c->call("run.get", {{"run_id", *run_id}});
      if (!g) return report(g.error(), err);
      if (terminal((*g)["run"]["state"])) return final_code(*c, *run_id, summary, o.json_out);
    }
    std::map<int, protocol::SampleMessage> latest;  // by unit
    for (;;) {
      auto m = c->next_message(30000);
      if (!m) {
        if (m.error().code == ClientErrc::timeout) continue;  // a long settle: quiet but alive
        if (tty_line) progress.line("fogctl: connection to fogbenchd lost; reconnecting");
        lost_since = SteadyClock::now();
        break;
      }
      if ((*m)["run_id"] != *run_id) continue;
      if (raw && ((*m)["type"] == "sample" || (*m)["type"] == "event")) out << m->dump() << '\n' << std::flush;
      if ((*m)["type"] == "sample") {
        auto s = protocol::sample_message_from_json(*m);
        if (!s) return report(ClientError{ClientErrc::protocol, s.error(), std::nullopt, {}}, err);
        latest[s->unit] = *s;
        if (tty_line) {
          std::ostringstream line;
          line << "run " << *run_id << " " << s->state << " " << s->phase << " step " << s->step << "  "
               << duration_text(s->elapsed_s) << " elapsed, " << duration_text(s->remaining_s) << " left  chamber "
               << num_text(s->chamber_c, 1) << "/" << num_text(s->setpoint_c, 1) << " C";
          for (const auto& [u, x] : latest)
            line << "  " << x.serial << " T1 " << num_text(x.t1_c) << " T2 " << num_text(x.t2_c) << " drift "
                 << num_text(x.gyro_dph) << " comp " << num_text(x.compensated_dph) << " dph";
          if (const auto w = progress.width(); w && line.str().size() > w - 1) {
            // Too wide for the terminal: every unit's drift and compensated rate kept, the
            // words and the thermistors left out (docs/cli.md, "Progress").
            line.str("");
            line << "run " << *run_id << " " << s->state << " " << s->step << "  " << duration_text(s->elapsed_s) << ", "
                 << duration_text(s->remaining_s) << " left  " << num_text(s->chamber_c, 1) << "/" << num_text(s->setpoint_c, 1)
                 << "C";
            for (const auto& [u, x] : latest)
              line << "  " << x.serial << " " << num_text(x.gyro_dph) << "/" << num_text(x.compensated_dph);
            line << " dph";
          }
          // A phase of the profile (its step and kind) is what gets a line of its own.
          progress.update(s->state + " " + s->phase + " " + std::to_string(s->step), line.str());
        }
      } else if ((*m)["type"] == "event") {
        auto e = protocol::event_message_from_json(*m);
        if (!e) return report(ClientError{ClientErrc::protocol, e.error(), std::nullopt, {}}, err);
        if (e->kind != "state") continue;
        const std::string to = e->detail.value("to", "");
        if (tty_line) progress.line("run " + std::to_string(*run_id) + ": " + to + " (" + e->detail.value("reason", "") + ")");
        if (terminal(to)) {
          // The analysis events follow the state change; run.get is answered after them. A
          // daemon that is stopping closes this connection right after the event: the
          // summary then comes from a new connection (the outer loop), when it is back.
          auto g = c->call("run.get", {{"run_id", *run_id}});
          if (g) {
            progress.finish();
            return final_code(*c, *run_id, summary, o.json_out);
          }
          lost_since = SteadyClock::now();
          break;
        }
      }
    }
  }
}

}  // namespace fogbench::cli::commands
