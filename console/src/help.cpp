// The wrapping --help formatter (text.hpp).
#include <sstream>
#include <string>

#include "fogbench/console/text.hpp"

namespace fogbench::console {
namespace {

constexpr std::size_t kHelpWidth = 100;  // columns, when the output has no width of its own
constexpr std::size_t kLeast = 24;       // a description column narrower than this wraps as a paragraph

// Each line of `text` wrapped at `width` (at least 1), joined with '\n'.
std::string wrap_lines(const std::string& text, std::size_t width) {
  std::string out;
  std::istringstream in(text);
  std::string line;
  bool first = true;
  while (std::getline(in, line)) {
    for (const auto& piece : wrap_text(line, width)) {
      if (!first) out += '\n';
      out += piece;
      first = false;
    }
  }
  if (!text.empty() && text.back() == '\n') out += '\n';
  return out;
}

class WrappingFormatter : public CLI::Formatter {
 public:
  explicit WrappingFormatter(std::function<std::size_t()> width) : width_(std::move(width)) {}

  // CLI11 indents a description's continuation lines to the description column.
  std::string make_option_desc(const CLI::Option* opt) const override {
    return wrap_lines(CLI::Formatter::make_option_desc(opt), description_width());
  }
  std::string make_subcommand(const CLI::App* sub) const override {
    std::stringstream out;
    CLI::detail::format_help(out, sub->get_display_name(true), wrap_lines(sub->get_description(), description_width()),
                             get_column_width());
    return out.str();
  }
  std::string make_description(const CLI::App* app) const override {
    return wrap_lines(CLI::Formatter::make_description(app), help_width());
  }
  std::string make_footer(const CLI::App* app) const override {
    return wrap_lines(CLI::Formatter::make_footer(app), help_width());
  }

 private:
  std::size_t help_width() const {
    const std::size_t w = width_ ? width_() : 0;
    return w == 0 ? kHelpWidth : w;
  }
  std::size_t description_width() const {
    const std::size_t w = help_width(), col = get_column_width();
    return w > col + kLeast ? w - col : kLeast;
  }

  std::function<std::size_t()> width_;
};

}  // namespace

std::shared_ptr<CLI::Formatter> wrapping_help_formatter(std::function<std::size_t()> width) {
  return std::make_shared<WrappingFormatter>(std::move(width));
}

}  // namespace fogbench::console
