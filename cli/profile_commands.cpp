// fogctl profile list|validate: the shipped temperature profiles, and a profile file checked
// (its syntax and, with --min/--max/--max-rate, a chamber's limits) before a run is started.
#include <CLI/CLI.hpp>
#include <filesystem>
#include <iostream>
#include <map>
#include <optional>
#include <nlohmann/json.hpp>

#include "client.hpp"
#include "client_commands.hpp"
#include "common.hpp"
#include "table.hpp"

namespace fogbench::cli {

namespace {

struct ListOptions {
  bool json = false;
};

int run_profile_list(const ListOptions& o, std::ostream& out, std::ostream& err) {
  // The first directory that has a name wins, as load_profile looks them up.
  std::map<std::string, std::filesystem::path> found;
  for (const auto& d : profile_dirs()) {
    std::error_code ec;
    for (const auto& e : std::filesystem::directory_iterator(d, ec)) {
      if (e.path().extension() != ".profile") continue;
      found.emplace(e.path().stem().string(), e.path());
    }
  }
  nlohmann::json j = nlohmann::json::array();
  Table t({"profile", "steps", "nominal", "file"});
  bool bad = false;
  for (const auto& [name, path] : found) {
    auto p = load_profile(path.string());
    if (!p) {
      err << "fogctl profile list: " << p.error() << "\n";
      bad = true;
      continue;
    }
    const double s = p->nominal_duration_s();
    j.push_back({{"name", name}, {"steps", p->steps.size()}, {"nominal_duration_s", s}, {"path", path.string()}});
    t.add({name, std::to_string(p->steps.size()), commands::duration_text(s), path.string()});
  }
  if (o.json) out << j.dump() << "\n";
  else if (found.empty()) {
    // A copied or installed fogctl with no shipped profiles beside it: where it looked, and the
    // variable that adds a folder (issue 28).
    std::string where;
    for (const auto& d : profile_dirs()) where += (where.empty() ? "" : ", ") + d.string();
    out << "no profiles found in " << where << " (set FOGBENCH_PROFILE_DIR to the folder that holds them)\n";
  }
  else out << t.str();
  return bad ? kExitError : kExitOk;
}

struct ValidateOptions {
  std::vector<std::string> files;
  std::optional<double> min_c, max_c, max_rate_c_per_min;
  bool json = false;
};

int run_profile_validate(const ValidateOptions& o, std::ostream& out, std::ostream& err) {
  const int limits_given = o.min_c.has_value() + o.max_c.has_value() + o.max_rate_c_per_min.has_value();
  if (limits_given != 0 && limits_given != 3) {
    err << "fogctl profile validate: --min, --max and --max-rate go together (a chamber's limits)\n";
    return kExitError;
  }
  int code = kExitOk;
  nlohmann::json j = nlohmann::json::array();
  for (const auto& f : o.files) {
    auto p = load_profile(f);
    std::string error;
    if (!p) {
      error = p.error();
    } else if (limits_given) {
      if (auto ok = profiles::check_limits(*p, {*o.min_c, *o.max_c, *o.max_rate_c_per_min}); !ok)
        error = ok.error().to_string() + (ok.error().line ? "\n" + ok.error().excerpt() : "");
    }
    if (!error.empty()) {
      code = kExitError;
      if (!o.json) err << "fogctl profile validate: " << error << "\n";
      j.push_back({{"file", f}, {"valid", false}, {"error", error}});
      continue;
    }
    const double s = p->nominal_duration_s();
    j.push_back({{"file", f}, {"valid", true}, {"steps", p->steps.size()}, {"nominal_duration_s", s}});
    if (!o.json)
      out << f << ": valid, " << p->steps.size() << " steps, " << commands::duration_text(s) << " nominal"
          << (limits_given ? ", within the chamber's limits" : "") << "\n";
  }
  if (o.json) out << j.dump() << "\n";
  return code;
}

}  // namespace

void add_profile_commands(CLI::App& app, int& code) {
  auto* p = app.add_subcommand("profile", "Temperature profiles: the shipped ones, and a file checked before a run");
  p->require_subcommand(1);
  static ListOptions lo;
  auto* l = p->add_subcommand("list", "The shipped profiles (and those in $FOGBENCH_PROFILE_DIR): steps and nominal length");
  l->add_flag("--json", lo.json, "Print JSON for machines");
  l->callback([&] { code = run_profile_list(lo, std::cout, std::cerr); });
  static ValidateOptions vo;
  auto* v = p->add_subcommand("validate", "Check profile files (or shipped names): syntax, and a chamber's limits when given; exit 2 on the first error of each");
  v->add_option("profiles", vo.files, "Profile files or shipped names")->required();
  v->add_option("--min", vo.min_c, "The chamber's lowest setpoint, degC");
  v->add_option("--max", vo.max_c, "The chamber's highest setpoint, degC");
  v->add_option("--max-rate", vo.max_rate_c_per_min, "The chamber's fastest ramp, degC/min");
  v->add_flag("--json", vo.json, "Print JSON for machines");
  v->callback([&] { code = run_profile_validate(vo, std::cout, std::cerr); });
}

}  // namespace fogbench::cli
