// fogctl allan: Allan deviation of a run's holds and of its compensated output.
#pragma once

#include <cstddef>
#include <expected>
#include <iosfwd>
#include <string>
#include <vector>

#include "common.hpp"
#include "fogbench/model/allan.hpp"
#include "fogbench/model/model.hpp"

namespace CLI {
class App;
}

namespace fogbench::cli {

struct AllanOptions {
  std::string run;                // run.csv
  std::string model;              // optional model.json: also the compensated output
  std::size_t min_samples = 600;  // shortest stretch analysed (10 min at 1 Hz)
  bool whole_run = false;         // every phase, not only holds
  bool json = false;
  RunInput input;
};
int run_allan(const AllanOptions& o, std::ostream& out, std::ostream& err);

// The series fogctl allan (and fogctl report's Allan section) analyse: each hold's even stretch
// of at least min_samples (model::allan::even_stretches; the whole run's with whole_run), then,
// with a model, the longest even stretch of the run compensated offline (gyro_dph - predict()).
struct AllanSeries {
  std::string what;  // "hold 3", "run" or "compensated"
  model::allan::Stretch stretch;
  std::vector<double> rate_dph;
};
std::expected<std::vector<AllanSeries>, std::string> allan_series(const model::RunData& run, const model::Model* m,
                                                                  std::size_t min_samples, bool whole_run);
void add_allan_command(CLI::App& app, int& code);

}  // namespace fogbench::cli
