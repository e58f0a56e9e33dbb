// fogbenchd's and fogbench-sim's --help within the terminal (issue 28's friction list): their
// option descriptions were one line each, up to 155 and 377 columns; the programs now share
// fogctl's wrapping formatter (fogbench/console/text.hpp). Run as a person would: $COLUMNS
// exported, or piped without it (then 100 columns).
#include "../daemon/live_bench.hpp"

#include <sys/wait.h>

#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "fogbench/console/text.hpp"

using namespace fogbench::daemon::test::live;

namespace {

struct Help {
  int status;
  std::vector<std::string> lines;
  std::string words;  // every word, in order, one space apart
};

Help help_of(const std::string& program, const std::string& env) {
  const auto out = std::filesystem::temp_directory_path() / ("fogbench-help-" + std::to_string(::getpid()));
  const std::string cmd = env + " '" + (kBin / program).string() + "' --help >'" + out.string() + "' 2>&1";
  const int s = std::system(cmd.c_str());
  Help h{WIFEXITED(s) ? WEXITSTATUS(s) : -1, {}, {}};
  std::ifstream in(out);
  for (std::string l; std::getline(in, l);) {
    h.lines.push_back(l);
    std::istringstream ws(l);
    for (std::string w; ws >> w;) h.words += w + " ";
  }
  std::filesystem::remove(out);
  return h;
}

std::size_t widest(const Help& h) {
  std::size_t w = 0;
  for (const auto& l : h.lines) w = std::max(w, fogbench::console::display_width(l));
  return w;
}

}  // namespace

TEST_CASE("fogbenchd and fogbench-sim --help fit the terminal's width, or 100 columns when piped, every word kept") {
  for (const std::string program : {"fogbenchd", "fogbench-sim"}) {
    INFO(program);
    const Help piped = help_of(program, "env -u COLUMNS");
    REQUIRE(piped.status == 0);
    REQUIRE(piped.lines.size() > 5);
    CHECK(widest(piped) <= 100u);
    const Help narrow = help_of(program, "COLUMNS=72");
    REQUIRE(narrow.status == 0);
    CHECK(widest(narrow) <= 72u);
    CHECK(narrow.lines.size() > piped.lines.size());  // it wrapped more, not cut
    CHECK(narrow.words == piped.words);               // the same words in the same order
  }
  // A description that was one line of 150 columns reads whole, under its column.
  const Help d = help_of("fogbenchd", "COLUMNS=72");
  CHECK(d.words.find("print the systemd drop-in that lets the unit open the serial devices a configuration file "
                     "names (DeviceAllow= lines) and exit") != std::string::npos);
}
