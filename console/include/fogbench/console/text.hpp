// Text for a person at a terminal: its width in columns, wrapped to a width, and the --help
// formatter of fogctl, fogbenchd and fogbench-sim that wraps within it.
#pragma once

#include <CLI/CLI.hpp>

#include <cstddef>
#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

namespace fogbench::console {

// The terminal's width in columns: $COLUMNS when exported (a number of at least 20), else the
// width of the terminal stdout is (100 when it does not say), else 0 (piped: no width).
std::size_t terminal_width();

// Columns a UTF-8 string takes in a terminal (one per code point: fogbench prints no wide or
// combining characters of its own).
std::size_t display_width(std::string_view text);

// `text` wrapped at spaces into lines of at most `width` columns (a longer word is cut at a code
// point); always at least one line.
std::vector<std::string> wrap_text(std::string_view text, std::size_t width);

// A CLI11 formatter that wraps option and command descriptions under their column, and the
// program's description and footer, within `width()` columns (called when help is printed;
// 0 means 100: help is read by a person even through `less`). Set it on the App before adding
// subcommands (they inherit it). The default width is terminal_width().
std::shared_ptr<CLI::Formatter> wrapping_help_formatter(std::function<std::size_t()> width = terminal_width);

}  // namespace fogbench::console
