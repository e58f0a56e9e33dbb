// fogctl's human tables: what a cell may carry to the terminal.
#include <catch2/catch.hpp>

#include <string>

#include "table.hpp"

using namespace fogbench::cli;

TEST_CASE("fogctl tables: a cell never carries a control character or a 100,000-byte name to the terminal") {
  Table t({"plan", "units"});
  t.add({"night\x1b]0;owned\x07", std::string(100000, 'n')});
  const std::string s = t.str();
  CHECK(s.find('\x1b') == std::string::npos);
  CHECK(s.find('\x07') == std::string::npos);
  CHECK(s.find("night\\x1B]0;owned\\x07") != std::string::npos);
  CHECK(s.find("... (100000 bytes)") != std::string::npos);
  CHECK(s.size() < 2000);
  // Cut at a character's start: "é" is two bytes and is not split.
  CHECK(printable(std::string(499, 'a') + "é", 500) == std::string(499, 'a') + "... (501 bytes)");
  CHECK(printable("Zoë", 500) == "Zoë");
}
