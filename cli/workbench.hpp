// fogctl's model workbench: compare, diagnose, fit --add, lineage and report. Each command is
// a function of its options writing to the given streams and returning the exit code
// (0 done and adequate, 1 the model fails or misses an effect, 2 an error).
#pragma once

#include <iosfwd>
#include <optional>
#include <string>
#include <vector>

#include "common.hpp"

namespace CLI {
class App;
}

namespace fogbench::cli {

struct CompareCommandOptions {
  std::string model;
  std::vector<std::string> runs;
  double k_sigma = 3.0;          // failing where the smoothed residual is beyond k sigma_a
  int smooth_s = 61;             // residual smoother width, s (odd)
  double min_duration_s = 60.0;  // shortest failing interval reported, s
  bool json = false;
  bool series = false;           // --json: include the measured/predicted/residual series
  RunInput input;
};
int run_compare(const CompareCommandOptions& o, std::ostream& out, std::ostream& err);

struct DiagnoseCommandOptions {
  std::string model;
  std::vector<std::string> runs;        // the fit run first, then held-out runs
  std::vector<std::string> candidates;  // extra candidate terms beyond the library
  std::optional<int> max_lag_s;         // lags searched, s (default: the model's)
  std::string search = "language";      // library | language
  int max_terms = 5;                    // greedy forward selection: terms added at most
  int tau_points = 12;                  // time constants of lp and warm on the log grid 30 s .. 4 h
  // The runs' samples in all, at most (model::workbench::DiagnoseOptions::max_samples): larger
  // files are refused before they are read, by their rows.
  std::size_t max_samples = 2'000'000;
  bool json = false;
  bool progress = false;                // progress lines on stderr even when it is not a terminal
  RunInput input;
};
int run_diagnose(const DiagnoseCommandOptions& o, std::ostream& out, std::ostream& err);

// fogctl fit --model M --add TERM run.csv -o M2.json
struct FitAddOptions {
  std::string model;
  std::string add;
  std::string run;
  std::string output;
  bool json = false;
  RunInput input;
};
int run_fit_add(const FitAddOptions& o, std::ostream& out, std::ostream& err);

struct LineageOptions {
  std::string model;
  std::vector<std::string> runs;
  bool json = false;
  RunInput input;
};
int run_lineage(const LineageOptions& o, std::ostream& out, std::ostream& err);

struct ReportOptions {
  std::string model;
  std::vector<std::string> runs;  // the fit run first, then held-out runs
  std::string output;             // report.html
  double threshold = 0.2;         // pass when compensated std / raw std is under this
  std::size_t max_points = 3000;  // plotted samples per series at most
  // A rate-sequence CSV (fogctl scale-factor's input): its scale factor over temperature as a
  // section of the page (report_scale_factor.hpp); "" for none.
  std::string scale_factor;
  RunInput input;
};
int run_report(const ReportOptions& o, std::ostream& out, std::ostream& err);

// Registers compare, diagnose, lineage and report on the app.
void add_workbench_commands(CLI::App& app, int& code);

}  // namespace fogbench::cli
