// What every fogctl command shares: loading runs, models and profiles with errors that name
// the file and the place, and the conventions of exit codes and output.
#pragma once

#include <expected>
#include <filesystem>
#include <iosfwd>
#include <optional>
#include <string>
#include <vector>

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
};

std::expected<model::RunData, std::string> load_run(const std::string& path, const RunInput& in);
// Adds --map and --resample to a command that reads runs.
void add_run_input(CLI::App* command, RunInput& in);
std::expected<model::Model, std::string> load_model(const std::string& path);
std::expected<void, std::string> write_text(const std::string& path, const std::string& text);

// A profile named `exp1` (a shipped one, found in $FOGBENCH_PROFILE_DIR, the source tree or
// the installed share/fogbench/profiles) or a file path.
std::expected<profiles::Profile, std::string> load_profile(const std::string& name_or_path);
std::vector<std::filesystem::path> profile_dirs();

// UTC now as ISO 8601, for models' created_at (model/ reads no clock).
std::string now_iso8601();

}  // namespace fogbench::cli
