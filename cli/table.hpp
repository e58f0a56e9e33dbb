// Human-readable tables for the terminal: a header, aligned columns, numbers right-aligned.
#pragma once

#include <string>
#include <string_view>
#include <vector>

namespace fogbench::cli {

// `text` safe to print in a terminal cell: control characters (U+0000..U+001F, U+007F) as
// \xNN, at most `max_bytes` bytes (then "..." and the full length). The daemon refuses such
// names at every entry (storage::check_stored_text); this guards what older stores hold.
std::string printable(std::string_view text, std::size_t max_bytes = 500);

class Table {
 public:
  explicit Table(std::vector<std::string> header) : header_(std::move(header)) {}
  // Cells are shown through printable(): a stored name can never act on the reader's terminal.
  void add(std::vector<std::string> row) {
    for (auto& cell : row) cell = printable(cell);
    rows_.push_back(std::move(row));
  }
  std::string str() const;

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
