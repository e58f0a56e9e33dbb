// fogctl's --help within the width (issue 28, point 1): descriptions wrapped under their column,
// no word lost. CLI11's own formatter printed them on one line, up to 250 columns.
#include <catch2/catch.hpp>

#include <sstream>
#include <string>
#include <vector>

#include "help_format.hpp"
#include "table.hpp"

using namespace fogbench::cli;

namespace {

std::vector<std::string> lines_of(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  for (std::string l; std::getline(in, l);) out.push_back(l);
  return out;
}

std::string words_of(const std::string& text) {
  std::istringstream in(text);
  std::string w, out;
  while (in >> w) out += w + " ";
  return out;
}

const std::string kLong =
    "A rate-sequence CSV of the unit (fogctl scale-factor's input): adds its scale factor over temperature, with "
    "plots of the sensitivity against the coil temperature and of each plateau's step residuals, in ppm of the full "
    "scale, and a note for the plateaus whose coil moved while the table turned";

struct Width {
  explicit Width(std::size_t w) { set_output_width(w); }
  ~Width() { set_output_width(static_cast<std::size_t>(-1)); }  // back to detecting it
};

}  // namespace

TEST_CASE("help: descriptions wrap under their column within the output width, every word kept") {
  for (std::size_t width : {100u, 60u}) {
    Width w(width);
    CLI::App app{"fogctl: " + kLong};
    app.formatter(wrapping_help_formatter());
    std::string path;
    app.add_option("--scale-factor", path, kLong);
    auto* sub = app.add_subcommand("report", kLong);
    sub->add_option("--map", path, kLong);
    for (const std::string& help : {app.help(), sub->help()}) {
      INFO(help);
      for (const auto& l : lines_of(help)) CHECK(display_width(l) <= width);
    }
    // Every word of the description is there, in order, the continuations under the column.
    const std::string help = app.help();
    std::string joined;
    bool in_option = false;
    for (const auto& l : lines_of(help)) {
      if (l.rfind("  --scale-factor", 0) == 0) in_option = true;
      else if (in_option && l.rfind(std::string(30, ' '), 0) != 0) in_option = false;
      if (in_option) joined += l + " ";
    }
    CHECK(words_of(joined) == "--scale-factor TEXT " + words_of(kLong));
  }
}

TEST_CASE("help: piped or --wide, help still fits 100 columns") {
  Width w(0);  // what output_width() says when piped or with --wide
  CLI::App app{"fogctl"};
  app.formatter(wrapping_help_formatter());
  std::string path;
  app.add_option("--scale-factor", path, kLong);
  for (const auto& l : lines_of(app.help())) CHECK(display_width(l) <= 100u);
}
