// fogctl scale-factor RUN.csv: the scale factor over temperature of a rate-sequence run
// (model::sf::fit; docs/scale-factor.md), and the rate-sequence CSV `fogctl simulate
// --rate-sequence` writes. Functions of their options writing to the given streams, so tests
// call them directly.
#pragma once

#include <expected>
#include <iosfwd>
#include <string>
#include <string_view>
#include <vector>

#include "fogbench/model/scale_factor.hpp"
#include "fogbench/sim/scale_factor.hpp"
#include "simulate_profile.hpp"

namespace CLI {
class App;
}

namespace fogbench::cli {

// The rate-sequence CSV of a simulated run's first unit: time_s, plateau (the profile's step),
// setpoint_c, chamber_c, t1_c, t2_c, rate_in_dps (commanded), rate_out_dps (the gyro's output:
// its bias and noise plus the true scale factor applied to the input, at the true coil
// temperature T1 and its rate).
std::string rate_sequence_csv(const SimulatedRun& run, const sim::ScaleFactorTruth& truth, const sim::RateSequence& seq);

// What parse_rate_csv left out of the fit, and why (a daemon's export, fogctl run export, has
// both: the seconds without a gyro reading, and the profile steps without a rate sequence).
struct RateCsvSkipped {
  // Rows whose rate_out_dps is empty: a second the daemon stored without a gyro reading.
  std::size_t no_gyro_reading = 0;
  // Rows with a gyro reading whose coil temperature cell is empty: a second stored without the
  // thermistor's reading (flagged missing by the daemon, e.g. before its first poll).
  std::size_t no_coil_reading = 0;
  std::string coil_column = "t1_c";
  // Plateaus whose every row has rate_in_dps 0 (the table at rest throughout: a setpoint, ramp
  // or settle step, a hold without rate lines), in file order, and their rows.
  std::vector<int> at_rest_plateaus;
  std::size_t at_rest_rows = 0;
  // "" when nothing was skipped, else one sentence saying what and why.
  std::string text() const;
};

// Reads a rate-sequence CSV (columns time_s, plateau, rate_in_dps, rate_out_dps and the coil
// temperature column `coil_column`, any others ignored; '#' lines are comments). Errors name
// the source, line and column: "run.csv:12: column 3 'rate_in_dps': not a number: 'x'". A row
// with an empty rate_out_dps cell is left out (counted in `skipped`, whatever its other cells),
// and one with an empty coil temperature; so is a plateau with no rate step (all rates 0). A
// file with nothing left is an error.
std::expected<model::sf::RateRecord, std::string> parse_rate_csv(std::string_view text, const std::string& source,
                                                                 const std::string& coil_column = "t1_c",
                                                                 RateCsvSkipped* skipped = nullptr);

// Reads a rate-sequence CSV and fits it (options validated first); the error names the file,
// and the line and column or the plateau and step.
std::expected<model::sf::Result, std::string> fit_rate_file(const std::string& path, const model::sf::Options& fo,
                                                            const std::string& coil_column = "t1_c",
                                                            RateCsvSkipped* skipped = nullptr);

// "v +- se unit (1 sigma)" with at least two significant digits of se, or "not identified: why".
std::string coefficient_text(const model::sf::Coefficient& c, int digits, const std::string& unit);

struct ScaleFactorOptions {
  std::string run;                 // RUN.csv
  double settle_s = 5.0;           // dropped at the start of each rate step, s
  double t0_c = 20.0;              // the model form's reference temperature, degC
  std::string coil_column = "t1_c";
  bool json = false;
};
int run_scale_factor(const ScaleFactorOptions& o, std::ostream& out, std::ostream& err);

void add_scale_factor_command(CLI::App& app, int& code);

}  // namespace fogbench::cli
