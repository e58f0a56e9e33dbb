// fogctl coefficients: a model as the gyro's firmware evaluates it (model/firmware.hpp), with a
// reference vector for testing a port.
#pragma once

#include <iosfwd>
#include <string>

#include "client_commands.hpp"
#include "common.hpp"

namespace CLI {
class App;
}

namespace fogbench::cli {

struct CoefficientsOptions {
  std::string model;         // model.json (from `fit -o` or `model get -o`), or a serial: its current model from fogbenchd
  commands::Common daemon;   // where fogbenchd is, for a serial
  std::string format = "json";  // json|csv|c
  std::string name = "fogcomp_model_unit";  // the C initializer's name
  std::string output;        // -o FILE (default: standard output)
  std::string run;           // the reference vector's inputs: a run's CSV (default: exp1 simulated)
  std::string reference;     // --reference FILE: the reference vector as CSV
  double dt_s = 1.0;         // the firmware's sample interval, s
  bool single = false;       // --float: the reference vector in single precision (a FOGCOMP_FLOAT build)
  bool late = false;         // --late: compute terms that would read the future as late as needed
  RunInput input;
};
int run_coefficients(const CoefficientsOptions& o, std::ostream& out, std::ostream& err);
void add_coefficients_command(CLI::App& app, int& code);

}  // namespace fogbench::cli
