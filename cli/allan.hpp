// fogctl allan: Allan deviation of a run's holds and of its compensated output.
#pragma once

#include <cstddef>
#include <iosfwd>
#include <string>

#include "common.hpp"

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
void add_allan_command(CLI::App& app, int& code);

}  // namespace fogbench::cli
