// Human-readable tables for the terminal: a header, aligned columns, numbers right-aligned.
#pragma once

#include <string>
#include <vector>

namespace fogbench::cli {

class Table {
 public:
  explicit Table(std::vector<std::string> header) : header_(std::move(header)) {}
  void add(std::vector<std::string> row) { rows_.push_back(std::move(row)); }
  std::string str() const;

 private:
  std::vector<std::string> header_;
  std::vector<std::vector<std::string>> rows_;
};

// Fixed-point with `digits` decimals; "-" for NaN.
std::string fixed(double v, int digits = 2);

}  // namespace fogbench::cli
