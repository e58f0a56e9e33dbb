// Human-readable tables for the terminal: a header, aligned columns, numbers right-aligned.
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "fogbench/console/text.hpp"

namespace fogbench::cli {

// `text` safe to print in a terminal cell: control characters (U+0000..U+001F, U+007F) as
// \xNN, at most `max_bytes` bytes (then "..." and the full length). The daemon refuses such
// names at every entry (storage::check_stored_text); this guards what older stores hold.
std::string printable(std::string_view text, std::size_t max_bytes = 500);

// How wide human output may be, in terminal columns (0: whole lines, as `--wide` asks). Unless
// set, the limit is console::terminal_width(): $COLUMNS when exported (a number of at least 20),
// else the terminal's width when stdout is one, else 0: piped output keeps whole lines, for grep
// and files.
void set_output_width(std::size_t columns);
std::size_t output_width();

// Columns a UTF-8 string takes, and text wrapped at spaces to a width: fogbench/console/text.hpp,
// shared with fogbenchd's and fogbench-sim's --help.
using console::display_width;
using console::wrap_text;

// A command's text output within `width` columns (0: as it is): each line wider than the width
// is wrapped at spaces, its continuation lines indented two more than the line (a sentence,
// a note, a hint; tables are already fitted by Table::str and pass through unchanged).
std::string fit_lines(std::string_view text, std::size_t width);

class Table {
 public:
  explicit Table(std::vector<std::string> header) : header_(std::move(header)) {}
  // Cells are shown through printable(): a stored name can never act on the reader's terminal.
  void add(std::vector<std::string> row) {
    for (auto& cell : row) cell = printable(cell);
    rows_.push_back(std::move(row));
  }
  // Aligned within output_width(): when the natural table is wider, the text columns are
  // narrowed (widest first, none below 10 columns or its header's longest word) and their cells
  // wrapped onto continuation lines; numbers never wrap.
  std::string str() const { return str(output_width()); }
  std::string str(std::size_t max_width) const;  // 0: no limit

 private:
  std::vector<std::string> header_;
  std::vector<std::vector<std::string>> rows_;
};

// Fixed-point with `digits` decimals; "-" for NaN.
std::string fixed(double v, int digits = 2);

// Four significant digits, "-" for NaN or infinity: coefficients span 1e-4 (deg/h per degC^2)
// to 10 (deg/h per degC/min).
std::string sig(double v);

// A ratio as a percentage (0.183 -> "18.3%" with one decimal), "-" for NaN or infinity.
std::string pct(double ratio, int decimals = 1);

}  // namespace fogbench::cli
