// fogctl's --help within the terminal (issue 28, point 1): CLI11 prints each option's and
// command's description on one line, up to 250 columns; this formatter wraps them at spaces
// under the description column, and the command's description and footer at the width
// (console::wrapping_help_formatter, shared with fogbenchd and fogbench-sim).
#pragma once

#include <CLI/CLI.hpp>
#include <memory>

namespace fogbench::cli {

// The width is output_width() (table.hpp: --wide, $COLUMNS, the terminal), or 100 columns when
// that is 0 (piped, or --wide): help is read by a person even through `less`.
std::shared_ptr<CLI::Formatter> wrapping_help_formatter();

}  // namespace fogbench::cli
