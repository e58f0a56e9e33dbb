// The Prometheus text exposition of fogbenchd (metrics.hpp). Names follow Prometheus' conventions:
// the fogbench_ prefix, base units in the name (_seconds, _bytes, _celsius), _total on counters.
// The gyro rate keeps the domain's unit, deg/h (_degrees_per_hour): in rad/s a drift of 0.01 deg/h
// is 4.8e-8, unreadable on a dashboard, and nothing sums it with other rates. A value not read
// (null in status) has no sample rather than a made-up one.
#include "fogbench/daemon/metrics.hpp"

#include <charconv>
#include <cmath>
#include <vector>

namespace fogbench::daemon {

using nlohmann::json;

std::string escape_label_value(std::string_view v) {
  std::string out;
  out.reserve(v.size());
  for (char c : v) {
    if (c == '\\') out += "\\\\";
    else if (c == '"') out += "\\\"";
    else if (c == '\n') out += "\\n";
    else out += c;
  }
  return out;
}

namespace {

std::string number(double v) {
  if (std::isnan(v)) return "NaN";
  if (std::isinf(v)) return v > 0 ? "+Inf" : "-Inf";
  char buf[64];
  auto r = std::to_chars(buf, buf + sizeof buf, v);  // the shortest text that reads back as v
  return std::string(buf, r.ptr);
}

using Labels = std::vector<std::pair<std::string, std::string>>;

class Writer {
 public:
  // A family: its HELP and TYPE lines once, before its first sample.
  void family(const std::string& name, const char* type, const std::string& help) {
    out_ += "# HELP " + name + " " + help + "\n# TYPE " + name + " " + type + "\n";
  }
  void sample(const std::string& name, const Labels& labels, double v) {
    out_ += name;
    if (!labels.empty()) {
      out_ += '{';
      for (std::size_t i = 0; i < labels.size(); ++i) {
        if (i) out_ += ',';
        out_ += labels[i].first + "=\"" + escape_label_value(labels[i].second) + "\"";
      }
      out_ += '}';
    }
    out_ += ' ' + number(v) + '\n';
  }
  // A sample from a JSON number; none for null (not read).
  void sample(const std::string& name, const Labels& labels, const json& v) {
    if (v.is_number()) sample(name, labels, v.get<double>());
    else if (v.is_boolean()) sample(name, labels, v.get<bool>() ? 1.0 : 0.0);
  }
  std::string take() { return std::move(out_); }

 private:
  std::string out_;
};

const json& at(const json& j, const char* key) {
  static const json null;
  return j.is_object() && j.contains(key) ? j[key] : null;
}

}  // namespace

std::string render_metrics(const MetricsInput& in) {
  Writer w;
  const json& s = in.status;
  const json& run = at(s, "run");
  const json& chamber = at(s, "chamber");

  w.family("fogbench_build_info", "gauge", "The daemon's release (label version); always 1.");
  w.sample("fogbench_build_info", {{"version", at(s, "version").is_string() ? at(s, "version").get<std::string>() : ""}}, 1.0);
  w.family("fogbench_simulated", "gauge", "1 on the mock bench (configuration simulated), else 0.");
  w.sample("fogbench_simulated", {}, at(s, "simulated"));
  w.family("fogbench_time_scale", "gauge", "Daemon seconds per wall second (--time-scale).");
  w.sample("fogbench_time_scale", {}, at(s, "time_scale"));
  w.family("fogbench_clock_seconds", "gauge", "The daemon's clock: daemon seconds since it started.");
  w.sample("fogbench_clock_seconds", {}, at(s, "clock_s"));

  w.family("fogbench_setpoint_celsius", "gauge", "The setpoint the daemon commands now, degC.");
  w.sample("fogbench_setpoint_celsius", {}, at(s, "setpoint_c"));
  w.family("fogbench_chamber_setpoint_celsius", "gauge", "The setpoint the chamber controller reports, degC.");
  w.sample("fogbench_chamber_setpoint_celsius", {}, at(chamber, "setpoint_c"));
  w.family("fogbench_chamber_air_celsius", "gauge", "The chamber's air temperature (process value), degC.");
  w.sample("fogbench_chamber_air_celsius", {}, at(chamber, "chamber_c"));
  w.family("fogbench_chamber_link_up", "gauge", "1 while the chamber answers its polls, 0 when its link is down.");
  {
    const json& link = at(chamber, "link");
    if (link == "up") w.sample("fogbench_chamber_link_up", {}, 1.0);
    else if (link == "down") w.sample("fogbench_chamber_link_up", {}, 0.0);
  }
  w.family("fogbench_chamber_alarm", "gauge", "1 while the chamber's alarm input is set.");
  w.sample("fogbench_chamber_alarm", {}, at(chamber, "alarm"));

  w.family("fogbench_run_active", "gauge", "1 while a run is active (pending, settling or running).");
  w.sample("fogbench_run_active", {}, run.is_object() ? 1.0 : 0.0);
  w.family("fogbench_run_state", "gauge", "The active run's state: 1 for the state it is in, 0 for the others (all 0 when idle).");
  for (const char* st : {"pending", "settling", "running"})
    w.sample("fogbench_run_state", {{"state", st}}, run.is_object() && at(run, "state") == st ? 1.0 : 0.0);
  if (run.is_object()) {
    w.family("fogbench_run_id", "gauge", "The active run's id.");
    w.sample("fogbench_run_id", {}, at(run, "id"));
    w.family("fogbench_run_elapsed_seconds", "gauge", "The active run's clock, daemon seconds.");
    w.sample("fogbench_run_elapsed_seconds", {}, at(run, "elapsed_s"));
    w.family("fogbench_run_remaining_seconds", "gauge", "The active run's profile time left, daemon seconds.");
    w.sample("fogbench_run_remaining_seconds", {}, at(run, "remaining_s"));
    w.family("fogbench_run_step", "gauge", "The active run's profile step (0-based).");
    w.sample("fogbench_run_step", {}, at(run, "step"));
    w.family("fogbench_run_samples_pending", "gauge",
             "Seconds of the active run's samples handed to the writer thread and not yet committed (0 or 1 normally).");
    w.sample("fogbench_run_samples_pending", {}, at(run, "samples_pending"));
  }

  const json& units = at(s, "units");
  // A unit's labels: its bench slot (when the status has one) and the serial in it, "" for an
  // empty slot without a default serial (the slot keeps such series apart).
  auto unit_labels = [](const json& u) {
    Labels l;
    if (u.contains("slot") && u["slot"].is_string()) l.push_back({"slot", u["slot"].get<std::string>()});
    l.push_back({"serial", u.contains("serial") && u["serial"].is_string() ? u["serial"].get<std::string>() : ""});
    return l;
  };
  w.family("fogbench_unit_rate_degrees_per_hour", "gauge", "Each unit's gyro output of the last second, deg/h.");
  if (units.is_array())
    for (const auto& u : units) w.sample("fogbench_unit_rate_degrees_per_hour", unit_labels(u), at(u, "gyro_dph"));
  w.family("fogbench_unit_temperature_celsius", "gauge", "Each unit's coil temperatures of the last second (sensor t1: centre, t2: wall), degC.");
  if (units.is_array())
    for (const auto& u : units)
      for (const char* t : {"t1", "t2"}) {
        Labels l = unit_labels(u);
        l.push_back({"sensor", t});
        w.sample("fogbench_unit_temperature_celsius", l, at(u, (std::string(t) + "_c").c_str()));
      }
  w.family("fogbench_unit_frames", "gauge", "Gyro frames averaged into each unit's last second.");
  if (units.is_array())
    for (const auto& u : units) w.sample("fogbench_unit_frames", unit_labels(u), at(u, "frames"));

  // The active run's quality counters: they start from 0 with each run (a counter reset).
  const json& quality = at(run, "quality");
  const std::vector<std::pair<const char*, const char*>> counters = {
      {"frames_lost", "Gyro frames lost (sequence gaps) in the active run, per unit; from 0 at each run."},
      {"frames_corrupt", "Gyro frames with a bad CRC in the active run, per unit; from 0 at each run."},
      {"samples_flagged", "Seconds stored with a quality flag in the active run, per unit; from 0 at each run."}};
  for (const auto& [key, help] : counters) {
    const std::string name = std::string("fogbench_unit_") + key + "_total";
    w.family(name, "counter", help);
    if (quality.is_array())
      for (const auto& q : quality) w.sample(name, {{"serial", q.value("serial", "")}}, at(q, key));
  }

  w.family("fogbench_ticks_total", "counter", "Seconds acquired since the daemon started.");
  w.sample("fogbench_ticks_total", {}, static_cast<double>(in.ticks));
  w.family("fogbench_ticks_skipped_total", "counter", "Seconds the loop was too late to acquire (stored as not read).");
  w.sample("fogbench_ticks_skipped_total", {}, static_cast<double>(in.ticks_skipped));
  w.family("fogbench_polls_late_total", "counter", "Ticks that used the previous period's device reading.");
  w.sample("fogbench_polls_late_total", {}, static_cast<double>(in.polls_late));
  w.family("fogbench_paced_slowed_total", "counter", "Simulated clock: ticks the schedule was moved back for a busy host.");
  w.sample("fogbench_paced_slowed_total", {}, static_cast<double>(in.paced_slowed));
  w.family("fogbench_tick_lateness_seconds", "gauge", "How late the last tick ran after its due time, wall seconds.");
  w.sample("fogbench_tick_lateness_seconds", {}, in.tick_lateness_s);
  w.family("fogbench_tick_lateness_max_seconds", "gauge", "The largest tick lateness since the daemon started, wall seconds.");
  w.sample("fogbench_tick_lateness_max_seconds", {}, in.tick_lateness_max_s);

  w.family("fogbench_store_size_bytes", "gauge", "The store's files on disk (database, -wal, -shm), bytes.");
  if (in.store_bytes) w.sample("fogbench_store_size_bytes", {}, static_cast<double>(*in.store_bytes));
  w.family("fogbench_clients", "gauge", "Connections open now, by transport (socket: the command socket, unix and TCP; web: the panel's WebSockets).");
  w.sample("fogbench_clients", {{"transport", "socket"}}, static_cast<double>(in.socket_clients));
  w.sample("fogbench_clients", {{"transport", "web"}}, static_cast<double>(in.web_clients));
  w.family("fogbench_http_requests_total", "counter", "HTTP requests answered by the web server since start.");
  w.sample("fogbench_http_requests_total", {}, static_cast<double>(in.http_requests));
  return w.take();
}

}  // namespace fogbench::daemon
