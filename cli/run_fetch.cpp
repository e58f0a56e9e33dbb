// --run N on the offline commands (fit, verify, compare, diagnose, report): a run stored by
// fogbenchd is fetched through its socket into a temporary CSV and handed to the command as the
// file it would otherwise be given; without --model (verify, compare, diagnose, report) the
// unit's current model is fetched the same way. --unit names the unit by serial or by index.
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cctype>
#include <filesystem>
#include <iostream>

#include "client_commands.hpp"
#include "common.hpp"
#include "fogbench/storage/csv.hpp"
#include "options.hpp"

namespace fogbench::cli {

namespace commands {

std::expected<int, ClientError> resolve_unit(Client& c, std::int64_t run_id, const std::string& unit) {
  auto r = c.call("run.get", {{"run_id", run_id}});
  if (!r) return std::unexpected(r.error());
  const auto& serials = (*r)["run"]["units"];
  std::string list;
  for (std::size_t i = 0; i < serials.size(); ++i) {
    const std::string s = serials[i].get<std::string>();
    if (s == unit) return static_cast<int>(i);  // a serial first: it is what the operator sees
    list += (list.empty() ? "" : ", ") + std::to_string(i) + " " + s;
  }
  const bool digits = !unit.empty() && unit.size() < 6 &&
                      std::all_of(unit.begin(), unit.end(), [](unsigned char ch) { return std::isdigit(ch) != 0; });
  if (digits && std::stoul(unit) < serials.size()) return static_cast<int>(std::stoul(unit));
  return std::unexpected(ClientError{ClientErrc::bad_option,
                                     "--unit " + unit + ": run " + std::to_string(run_id) +
                                         " has no unit of that serial or index (its units: " + list + ")",
                                     std::nullopt,
                                     {}});
}

}  // namespace commands

namespace {

using namespace commands;

struct TempFiles {
  std::vector<std::filesystem::path> paths;
  ~TempFiles() {
    std::error_code ec;
    for (const auto& p : paths) std::filesystem::remove(p, ec);
  }
};
TempFiles& temp_files() {
  static TempFiles t;
  return t;
}

std::filesystem::path temp_path(const std::string& stem, const std::string& ext) {
  auto p = std::filesystem::temp_directory_path() / ("fogctl-" + std::to_string(::getpid()) + "-" + stem + ext);
  temp_files().paths.push_back(p);
  return p;
}

[[noreturn]] void fail(const ClientError& e) {
  report(e, std::cerr);
  throw CLI::RuntimeError(kExitError);
}

struct Fetched {
  std::string csv;
  std::string serial;
};

Fetched fetch_to_csv(const Common& where, std::int64_t run_id, const std::string& unit_arg) {
  auto c = open(where);
  if (!c) fail(c.error());
  auto unit = resolve_unit(*c, run_id, unit_arg);
  if (!unit) fail(unit.error());
  auto d = fetch_run(*c, run_id, *unit);
  if (!d) fail(d.error());
  auto path = temp_path("run" + std::to_string(run_id) + "-unit" + std::to_string(*unit), ".csv");
  if (auto ok = storage::write_csv_file(path, *d); !ok) {
    std::cerr << "fogctl: " << ok.error().message << "\n";
    throw CLI::RuntimeError(kExitError);
  }
  auto g = c->call("run.get", {{"run_id", run_id}});
  if (!g) fail(g.error());
  const auto serial = (*g)["run"]["units"][static_cast<std::size_t>(*unit)].get<std::string>();
  set_display_name(path.string(), "run " + std::to_string(run_id) + " " + serial);
  set_command_form(path.string(), {"--run " + std::to_string(run_id) + " --unit " + serial, {}});
  return {path.string(), serial};
}

std::string fetch_model(const Common& where, const std::string& serial) {
  auto c = open(where);
  if (!c) fail(c.error());
  auto m = c->call("model.get", {{"serial", serial}});
  if (!m) fail(m.error());
  auto path = temp_path("model" + std::to_string((*m)["id"].get<std::int64_t>()), ".json");
  set_display_name(path.string(), "model " + std::to_string((*m)["id"].get<std::int64_t>()) + " of " + serial);
  set_command_form(path.string(), {"model-" + serial + ".json", "fogctl model get " + serial + " -o model-" + serial + ".json"});
  if (auto ok = write_text(path.string(), (*m)["model"].dump(2)); !ok) {
    std::cerr << "fogctl: " << ok.error() << "\n";
    throw CLI::RuntimeError(kExitError);
  }
  return path.string();
}

// Adds --socket/--connect/--token, --unit and --run to `command`, whose positional option
// `positional` takes the CSV files; `model` (may be null) is filled with the first run's unit's
// current model when not given.
void add_stored_run(CLI::App* command, const std::string& positional, bool fill_model) {
  auto* pos = command->get_option_no_throw(positional);
  if (!pos) return;
  CLI::Option* model = fill_model ? command->get_option_no_throw("--model") : nullptr;
  pos->required(false);
  if (model) model->required(false);
  struct Where {
    Common common;
    std::string unit = "0";
  };
  auto* w = new Where;  // lives as long as the app (a static's lifetime: fogctl runs one command)
  add_common(command, w->common, /*with_json=*/false);  // where --run is fetched
  command->add_option("--unit", w->unit, "With --run: the unit, by serial or by index in the run (default 0, the first)");
  command->add_option("--run")
      ->description("A run stored by fogbenchd (its id), fetched through its socket, instead of a CSV file" +
                    std::string(fill_model ? "; without --model, the unit's current model" : "") +
                    (pos->get_items_expected_max() > 1 ? " (repeatable)" : ""))
      ->take_all()
      ->each([pos, model, w](const std::string& v) {
        const std::int64_t id = parse_run_id("--run", v);
        const Fetched f = fetch_to_csv(w->common, id, w->unit);
        if (pos->get_items_expected_max() <= 1) pos->clear();
        pos->add_result(f.csv);
        pos->run_callback();
        if (model && model->count() == 0) {
          model->add_result(fetch_model(w->common, f.serial));
          model->run_callback();
        }
      });
}

}  // namespace

void add_stored_run_options(CLI::App& app) {
  if (auto* fit = find_subcommand(app, "fit")) add_stored_run(fit, "run", false);
  for (const char* name : {"verify", "compare", "diagnose", "report"})
    if (auto* c = find_subcommand(app, name)) add_stored_run(c, "runs", true);
}

}  // namespace fogbench::cli
