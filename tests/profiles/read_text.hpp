// Test helper: reads a file of the source tree (the shipped profiles) into a string.
#pragma once

#include <fstream>
#include <sstream>
#include <string>

inline std::string read_source_file(const std::string& relative_path) {
  std::ifstream in(std::string(FOGBENCH_SOURCE_DIR) + "/" + relative_path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}
