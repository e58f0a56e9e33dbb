// fogctl's wrapping --help formatter (help_format.hpp): the programs' shared one
// (fogbench/console/text.hpp) at fogctl's output width.
#include "help_format.hpp"

#include "fogbench/console/text.hpp"
#include "table.hpp"

namespace fogbench::cli {

std::shared_ptr<CLI::Formatter> wrapping_help_formatter() { return console::wrapping_help_formatter(output_width); }

}  // namespace fogbench::cli
