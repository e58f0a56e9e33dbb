// Terminal width and word wrapping (text.hpp).
#include <sys/ioctl.h>
#include <unistd.h>

#include <cstdlib>
#include <utility>

#include "fogbench/console/text.hpp"

namespace fogbench::console {
namespace {

bool utf8_continuation(char c) { return (static_cast<unsigned char>(c) & 0xC0) == 0x80; }

// The longest prefix of `text` that takes at most `width` columns (at least one code point),
// in bytes, cut at a code point.
std::size_t prefix_bytes(std::string_view text, std::size_t width) {
  std::size_t cols = 0, i = 0;
  while (i < text.size()) {
    std::size_t j = i + 1;
    while (j < text.size() && utf8_continuation(text[j])) ++j;
    if (cols + 1 > width && cols > 0) break;
    ++cols;
    i = j;
  }
  return i;
}

}  // namespace

std::size_t terminal_width() {
  if (const char* env = std::getenv("COLUMNS")) {
    char* end = nullptr;
    const long n = std::strtol(env, &end, 10);
    if (end != env && *end == '\0' && n >= 20) return static_cast<std::size_t>(n);
  }
  if (::isatty(STDOUT_FILENO)) {
    winsize ws{};
    if (::ioctl(STDOUT_FILENO, TIOCGWINSZ, &ws) == 0 && ws.ws_col >= 20) return ws.ws_col;
    return 100;  // a terminal that does not say its width
  }
  return 0;
}

std::size_t display_width(std::string_view text) {
  std::size_t n = 0;
  for (char c : text) n += utf8_continuation(c) ? 0 : 1;
  return n;
}

std::vector<std::string> wrap_text(std::string_view text, std::size_t width) {
  width = std::max<std::size_t>(width, 1);
  std::vector<std::string> lines;
  std::string line;
  std::size_t line_cols = 0;
  std::size_t pos = 0;
  while (pos < text.size()) {
    const std::size_t end = std::min(text.find(' ', pos), text.size());
    std::string_view word = text.substr(pos, end - pos);
    pos = end + 1;
    if (word.empty()) continue;
    const std::size_t cols = display_width(word);
    if (line_cols + cols + (line.empty() ? 0 : 1) <= width) {
      if (!line.empty()) line += ' ', ++line_cols;
      line += word;
      line_cols += cols;
      continue;
    }
    if (!line.empty()) lines.push_back(std::exchange(line, {}));
    while (display_width(word) > width) {  // a word longer than the column: cut it
      const std::size_t cut = prefix_bytes(word, width);
      lines.emplace_back(word.substr(0, cut));
      word.remove_prefix(cut);
    }
    line = word;
    line_cols = display_width(word);
  }
  if (!line.empty() || lines.empty()) lines.push_back(line);
  return lines;
}

}  // namespace fogbench::console
