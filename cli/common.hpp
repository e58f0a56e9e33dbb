// What every fogctl command shares: loading runs, models and profiles with errors that name
// the file and the place, and the conventions of exit codes and output.
#pragma once

#include <expected>
#include <filesystem>
#include <iosfwd>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "fogbench/model/model.hpp"
#include "fogbench/profiles/profile.hpp"

namespace CLI {
class App;
}

namespace fogbench::cli {

// Exit codes: 0 done (and passed), 1 a verification that failed its threshold, 2 an error,
// 3 marginal: the paper's ratio passed but the compensated output is not the model's noise.
inline constexpr int kExitOk = 0;
inline constexpr int kExitFailed = 1;
inline constexpr int kExitError = 2;
inline constexpr int kExitMarginal = 3;

// Options to read a run's CSV: --map canonical=header (repeatable), --resample S, --delimiter
// and --decimal-comma.
struct RunInput {
  std::vector<std::string> maps;
  std::optional<double> resample_s;
  std::vector<std::string> skip;  // optional columns the command does not use
  std::string delimiter;          // --delimiter: ',', ';', tab or "\t"; empty: detected
  bool decimal_comma = false;     // --decimal-comma
  std::string time_unit = "s";    // --time-unit: s or ms (the file's time_s column is read in this unit)
  // --quality: the data-quality check before physics (docs/data-quality.md): `check` cleans a
  // short dropout and an isolated gyro spike and refuses every other sensor problem, `clean`
  // cleans every cleanable one and refuses the rest, `warn` refuses nothing and warns, `off`
  // skips the check.
  std::string quality = "check";
  // --axis x|y|z (fit, verify, diagnose): the axis of a three-axis run (gyro_y_dph, gyro_z_dph
  // columns) the command analyses; empty: the model's axis where a model is given, else x.
  std::string axis;
  // The command as the user gave it, for hints that name a whole working command (e.g. "fogctl
  // fit run.csv"); empty: hints name the option only.
  std::string retry;
};

// What the data-quality check found and did on the runs a command loaded: one line per
// cleaned or warned problem (printed as `warning:` lines) and the flags as JSON.
struct QualityLog {
  std::vector<std::string> lines;
  nlohmann::json flags = nlohmann::json::array();  // [{run, sensor, kind, start_s, end_s, value, unit, evidence, action, remedy}]
  bool sensor_problem = false;                     // a problem was left in the data (--quality warn)
  std::string headline;                            // "a sensor problem: T1 lag at 0..5400 s" when sensor_problem
};

// A file fogctl made in the temporary directory for a stored run or model (--run): the name it
// is shown by in tables, reports and messages ("run 2 SIM-0001", "model 1 of SIM-0001") instead
// of a temporary path that is deleted when fogctl exits (issue 28). display_name of a path
// nobody named is the path itself.
void set_display_name(const std::string& path, std::string name);
std::string display_name(const std::string& path);
// A model file as a title names it: "model PATH", or a fetched one's name ("model 1 of SIM-0001").
std::string model_label(const std::string& path);
// How a command line a hint prints names such a file: a fetched run as `--run 2 --unit
// SIM-0001`, a fetched model as the file `fetch` writes (`model-SIM-0001.json`, with `fetch`
// the command that writes it: `fogctl model get SIM-0001 -o model-SIM-0001.json`); any other
// path as itself, with no fetch.
struct CommandForm {
  std::string arg;
  std::string fetch;
};
void set_command_form(const std::string& path, CommandForm form);
CommandForm command_form(const std::string& path);

// Reads a run's CSV and runs the data-quality check of `in.quality` on it: the run (cleaned
// where the mode cleans) or an error naming the file, the sensor, the interval and what to do.
// What was cleaned or warned is added to `log`, or printed to stderr as `warning:` lines when
// log is null (never silent).
std::expected<model::RunData, std::string> load_run(const std::string& path, const RunInput& in, QualityLog* log = nullptr);
// Adds --map, --resample, --delimiter, --decimal-comma, --time-unit and --quality to a command
// that reads runs.
void add_run_input(CLI::App* command, RunInput& in);
// Adds --axis to a command that analyses one axis of a three-axis run.
void add_axis_option(CLI::App* command, RunInput& in);
// `in` with the model's axis when --axis was not given (a model is one axis's: docs/cli.md).
RunInput with_model_axis(RunInput in, const model::Model& m);
std::expected<model::Model, std::string> load_model(const std::string& path);
std::expected<void, std::string> write_text(const std::string& path, const std::string& text);

// Where shipped files of a kind ("profiles", "plans") are looked for, in order: the folder in
// $FOGBENCH_PROFILE_DIR or $FOGBENCH_PLAN_DIR, <the executable's prefix>/share/fogbench/<kind>
// (installed, or the build tree, which lays them out the same), and the configured install
// prefix's share/fogbench/<kind>.
std::vector<std::filesystem::path> shipped_dirs(std::string_view kind);
// `name` as a file path, else `name` or `name`+`extension` in shipped_dirs(kind). The error
// names every folder searched and the variable that adds one.
std::expected<std::filesystem::path, std::string> find_shipped(std::string_view kind, const std::string& name,
                                                               std::string_view extension);
// A profile named `exp1` (a shipped one, see shipped_dirs) or a file path.
std::expected<profiles::Profile, std::string> load_profile(const std::string& name_or_path);
std::vector<std::filesystem::path> profile_dirs();

// UTC now as ISO 8601, for models' created_at (model/ reads no clock).
std::string now_iso8601();

}  // namespace fogbench::cli
