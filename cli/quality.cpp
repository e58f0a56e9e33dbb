// --quality on the model commands: the data-quality check, its cleaning and its refusals.
#include "quality.hpp"

#include <iostream>

#include "fogbench/model/model.hpp"
#include "run_identity.hpp"
#include "table.hpp"

namespace fogbench::cli {

nlohmann::json to_json(const model::QualityFlag& f, const std::string& run, const std::string& action) {
  return {{"run", run},           {"sensor", f.sensor},     {"kind", std::string(to_string(f.kind))},
          {"start_s", f.start_s}, {"end_s", f.end_s},       {"value", f.value},
          {"unit", f.unit},       {"evidence", f.evidence}, {"action", action},
          {"remedy", f.remedy},   {"cleanable", f.cleanable}};
}

std::expected<model::RunData, std::string> check_run_quality(model::RunData run, const std::string& path, const std::string& mode,
                                                             QualityLog* log, const std::string& retry) {
  if (mode == "off") return run;
  if (mode != "check" && mode != "clean" && mode != "warn")
    return std::unexpected("--quality " + mode + ": expected check, clean, warn or off");
  const auto report = model::assess_quality(run);
  if (report.ok()) return run;
  QualityLog local;
  QualityLog& l = log ? *log : local;
  // warn cleans nothing but what check would (a short dropout, an isolated spike), and refuses nothing.
  const auto policy = mode == "clean" ? model::CleanPolicy::all : model::CleanPolicy::by_default;
  auto cleaned = model::clean_run(run, report, policy);
  std::vector<std::string> lines;
  for (std::size_t i = 0; i < cleaned.cleaned.size(); ++i) {
    lines.push_back(path + ": cleaned " + cleaned.done[i]);
    l.flags.push_back(to_json(cleaned.cleaned[i], path, "cleaned"));
  }
  // What is left is refused, except with warn; a time unit is always refused (nothing can be
  // judged, or fitted, on time that is not in seconds).
  std::string refusal;
  bool any_sensor = false, any_cleanable = false;
  for (const auto& f : cleaned.remaining) {
    const bool time = f.kind == model::QualityKind::time_unit || f.kind == model::QualityKind::time_step;
    if (mode == "warn" && !time) {
      lines.push_back(path + ": a sensor problem left in the data (--quality warn): " + f.message());
      l.flags.push_back(to_json(f, path, "warned"));
      if (!l.sensor_problem) l.headline = "a sensor problem: " + f.sensor + " " + std::string(to_string(f.kind)) + " on " + path + " at " +
                                          fixed(f.start_s, 0) + ".." + fixed(f.end_s, 0) + " s";
      l.sensor_problem = true;
      continue;
    }
    l.flags.push_back(to_json(f, path, "refused"));
    refusal += "\n  " + f.message();
    if (time) {
      const std::string fix = f.kind == model::QualityKind::time_unit ? "--time-unit ms" : "--resample 1";
      refusal += "\n  to read it: add " + fix + " to the command" + (retry.empty() ? "" : " (" + retry + " " + fix + ")");
    } else {
      any_sensor = true;
      any_cleanable = any_cleanable || f.cleanable;
      if (mode == "check" && f.cleanable) refusal += " [cleanable: add --quality clean to the command]";
    }
  }
  if (!refusal.empty()) {
    std::string msg = path + (any_sensor ? ": a sensor problem, not physics: refused before any model is fitted or applied:"
                                         : ": time_s is not one sample per second: refused:") +
                      refusal;
    if (!lines.empty()) {
      msg += "\n  (would also clean:";
      for (const auto& s : lines) msg += " " + s + ";";
      msg += ")";
    }
    if (any_sensor)
      msg += std::string("\n  to go on anyway: ") +
             (any_cleanable ? "--quality clean flags the cleanable intervals (skipped, temperatures bridged); " : "") +
             "--quality warn uses the data as they are, at your risk";
    return std::unexpected(msg);
  }
  for (auto& s : lines) {
    if (log) log->lines.push_back(s);
    else std::cerr << "warning: " << s << "\n";
  }
  return std::move(cleaned.run);
}

std::expected<void, std::string> check_one_gyro(const std::vector<std::string>& paths, const std::string& mode,
                                                std::vector<std::string>& warnings) {
  if (mode == "off") return {};
  std::vector<std::pair<std::string, std::string>> serials;  // path, serial
  for (const auto& p : paths)
    for (const auto& [k, v] : csv_file_identity(p))
      if (k == "serial" && !v.empty()) serials.emplace_back(p, v);
  for (std::size_t i = 1; i < serials.size(); ++i) {
    if (serials[i].second == serials[0].second) continue;
    std::string msg = "runs of different gyros given as one gyro's: ";
    for (std::size_t j = 0; j < serials.size(); ++j) msg += (j ? ", " : "") + serials[j].first + " is " + serials[j].second;
    msg += " (their '# serial:' lines); a drift model describes one gyro: give the runs of one serial";
    if (mode == "warn") {
      warnings.push_back(msg + " (--quality warn: used as given)");
      return {};
    }
    return std::unexpected(msg + ", or --quality warn to use them anyway");
  }
  return {};
}

std::vector<std::string> identification_lines(const model::Model& m, const model::RunData& run) {
  return model::identification_warnings(m, run);
}

}  // namespace fogbench::cli
