// Loading runs, models and profiles for fogctl.
#include "common.hpp"

#include <algorithm>

#include <CLI/CLI.hpp>

#include <chrono>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <fstream>
#include <map>
#include <sstream>

#include "fogbench/model/json.hpp"
#include "quality.hpp"
#include "fogbench/storage/run_data.hpp"
#include "fogbench/storage/csv.hpp"

namespace fogbench::cli {

namespace {
std::map<std::string, std::string>& display_names() {
  static std::map<std::string, std::string> names;
  return names;
}
}  // namespace

std::map<std::string, CommandForm>& command_forms() {
  static std::map<std::string, CommandForm> forms;
  return forms;
}

void set_display_name(const std::string& path, std::string name) { display_names()[path] = std::move(name); }

void set_command_form(const std::string& path, CommandForm form) { command_forms()[path] = std::move(form); }

CommandForm command_form(const std::string& path) {
  const auto it = command_forms().find(path);
  return it == command_forms().end() ? CommandForm{path, {}} : it->second;
}

std::string model_label(const std::string& path) {
  const std::string name = display_name(path);
  return name == path ? "model " + path : name;
}

std::string display_name(const std::string& path) {
  const auto it = display_names().find(path);
  return it == display_names().end() ? path : it->second;
}

std::expected<model::RunData, std::string> load_run(const std::string& path, const RunInput& in, QualityLog* log) {
  storage::CsvOptions o;
  o.resample_s = in.resample_s;
  o.skip = in.skip;
  o.decimal_comma = in.decimal_comma;
  if (!in.delimiter.empty()) {
    const std::string& d = in.delimiter;
    if (d == "\\t" || d == "tab" || d == "\t") o.delimiter = '\t';
    else if (d == "," || d == ";") o.delimiter = d[0];
    else return std::unexpected("--delimiter " + d + ": expected ',', ';' or tab (\"\\t\" or tab)");
  }
  for (const auto& m : in.maps) {
    auto cm = storage::parse_column_mapping(m);
    if (!cm) return std::unexpected("--map " + m + ": " + cm.error().message);
    o.column_map.push_back(*cm);
  }
  if (in.time_unit == "ms") o.time_scale = 1e-3;
  else if (in.time_unit != "s") return std::unexpected("--time-unit " + in.time_unit + ": expected s or ms");
  const std::string name = display_name(path);
  if (name != path) o.source_name = name;  // a stored run (--run): "run 2 SIM-0001"
  model::Axis axis = model::Axis::x;
  if (!in.axis.empty()) {
    const auto a = model::axis_from_string(in.axis);
    if (!a) return std::unexpected("--axis " + in.axis + ": expected x, y or z");
    axis = *a;
  }
  auto r = storage::read_csv_file(path, o);
  if (!r) return std::unexpected(r.error().message);
  // The axis is picked before the quality check, which then judges that axis's gyro.
  auto picked = model::select_axis(std::move(*r), axis);
  if (!picked) return std::unexpected(picked.error());
  return check_run_quality(std::move(*picked), name, in.quality, log, in.retry);
}

void add_axis_option(CLI::App* c, RunInput& in) {
  c->add_option("--axis", in.axis,
                "The axis of a three-axis unit's run (gyro_y_dph, gyro_z_dph columns) to analyse: x, y or z (default: the "
                "model's axis, else x)")
      ->check(CLI::IsMember({"x", "y", "z"}));
}

RunInput with_model_axis(RunInput in, const model::Model& m) {
  if (in.axis.empty() && m.axis) in.axis = std::string(model::to_string(*m.axis));
  return in;
}

void add_run_input(CLI::App* c, RunInput& in) {
  c->add_option("--map", in.maps, "Column of another name: canonical=header, e.g. gyro_dph=Rate (repeatable)");
  c->add_option("--resample", in.resample_s, "Resample unevenly spaced time onto this step, s");
  c->add_option("--delimiter", in.delimiter,
                "Field separator: ',', ';' or tab (\"\\t\"); default: ';' or tab when the header row has no ',' (docs/csv.md)");
  c->add_flag("--decimal-comma", in.decimal_comma, "Numbers written with a decimal comma (1,5), with ';' or tab between the fields");
  c->add_option("--time-unit", in.time_unit, "Unit of the file's time_s column: s (default) or ms (converted to s as it is read)")
      ->check(CLI::IsMember({"s", "ms"}));
  c->add_option("--quality", in.quality,
                "Data-quality check before physics: check (default: cleans short dropouts and isolated gyro spikes, refuses other "
                "sensor problems), clean (cleans every cleanable one), warn (refuses nothing, warns), off; docs/data-quality.md")
      ->check(CLI::IsMember({"check", "clean", "warn", "off"}));
}

namespace {
std::expected<std::string, std::string> read_file(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) return std::unexpected(path + ": cannot open (" + std::strerror(errno) + ")");
  std::ostringstream s;
  s << f.rdbuf();
  return s.str();
}
}  // namespace

std::expected<model::Model, std::string> load_model(const std::string& path) {
  auto text = read_file(path);
  if (!text) return std::unexpected(text.error());
  auto m = model::model_from_text(*text);
  if (!m) return std::unexpected(path + ": not a fogbench model: " + m.error());
  return m;
}

std::expected<void, std::string> write_text(const std::string& path, const std::string& text) {
  // Write beside the target and rename, so an interrupted write never leaves half a file.
  const std::string tmp = path + ".tmp";
  {
    std::ofstream f(tmp, std::ios::binary | std::ios::trunc);
    if (!f) return std::unexpected(path + ": cannot write (" + std::strerror(errno) + ")");
    f << text;
    f.flush();
    if (!f) return std::unexpected(path + ": write failed (" + std::strerror(errno) + ")");
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) return std::unexpected(path + ": " + ec.message());
  return {};
}

namespace {
std::string_view shipped_variable(std::string_view kind) {
  return kind == "plans" ? "FOGBENCH_PLAN_DIR" : "FOGBENCH_PROFILE_DIR";
}
}  // namespace

std::vector<std::filesystem::path> shipped_dirs(std::string_view kind) {
  std::vector<std::filesystem::path> dirs;
  if (const char* env = std::getenv(std::string(shipped_variable(kind)).c_str()); env && *env) dirs.emplace_back(env);
  // Beside the executable: <prefix>/bin/../share/fogbench/<kind>, installed or in the build
  // tree (profiles/ and plans/CMakeLists.txt lay them out there too).
  std::error_code ec;
  if (const auto exe = std::filesystem::read_symlink("/proc/self/exe", ec); !ec)
    dirs.push_back(exe.parent_path().parent_path() / "share" / "fogbench" / kind);
  const auto installed = std::filesystem::path(FOGBENCH_DATA_DIR) / kind;
  if (std::find(dirs.begin(), dirs.end(), installed) == dirs.end()) dirs.push_back(installed);
  return dirs;
}

std::expected<std::filesystem::path, std::string> find_shipped(std::string_view kind, const std::string& name,
                                                               std::string_view extension) {
  if (std::filesystem::exists(name)) return std::filesystem::path(name);
  const auto dirs = shipped_dirs(kind);
  for (const auto& d : dirs)
    for (const auto& candidate : {d / name, d / (name + std::string(extension))})
      if (std::filesystem::is_regular_file(candidate)) return candidate;
  const std::string what = kind == "plans" ? "plan" : "profile";
  std::string where;
  for (const auto& d : dirs) where += (where.empty() ? "" : ", ") + d.string();
  return std::unexpected(what + " '" + name + "': no such file, and no shipped " + what + " of that name in " + where +
                         " (give a file's path, or set " + std::string(shipped_variable(kind)) + " to the folder that holds it)");
}

std::vector<std::filesystem::path> profile_dirs() { return shipped_dirs("profiles"); }

std::expected<profiles::Profile, std::string> load_profile(const std::string& name) {
  auto found = find_shipped("profiles", name, ".profile");
  if (!found) return std::unexpected(found.error());
  const std::filesystem::path path = *found;
  auto text = read_file(path.string());
  if (!text) return std::unexpected(text.error());
  auto p = profiles::parse_profile(*text, path.filename().string());
  if (!p) return std::unexpected(p.error().to_string() + "\n" + p.error().excerpt());
  return std::move(*p);
}

std::string now_iso8601() { return storage::iso8601_utc(std::chrono::system_clock::now()); }

}  // namespace fogbench::cli
