// Plain-text table rendering for fogctl's human output.
#include "table.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <utility>

namespace fogbench::cli {
namespace {
bool numeric(const std::string& s) {
  return !s.empty() && (std::isdigit(static_cast<unsigned char>(s[0])) || s[0] == '-' || s[0] == '+') &&
         s.find_first_not_of("0123456789+-.e%") == std::string::npos;
}
}  // namespace

std::string printable(std::string_view text, std::size_t max_bytes) {
  std::string out;
  std::size_t n = std::min(text.size(), max_bytes);
  if (n < text.size())  // cut at a character's start, not inside a UTF-8 sequence
    while (n > 0 && (static_cast<unsigned char>(text[n]) & 0xC0) == 0x80) --n;
  out.reserve(n + 32);
  for (std::size_t i = 0; i < n; ++i) {
    const auto c = static_cast<unsigned char>(text[i]);
    if (c < 0x20 || c == 0x7f) {
      char code[8];
      std::snprintf(code, sizeof code, "\\x%02X", c);
      out += code;
    } else {
      out += static_cast<char>(c);
    }
  }
  if (text.size() > max_bytes) out += "... (" + std::to_string(text.size()) + " bytes)";
  return out;
}

namespace {
constexpr std::size_t kAutoWidth = static_cast<std::size_t>(-1);
std::size_t g_output_width = kAutoWidth;

}  // namespace

void set_output_width(std::size_t columns) { g_output_width = columns; }

std::size_t output_width() {
  if (g_output_width == kAutoWidth) g_output_width = console::terminal_width();
  return g_output_width;
}

std::string fit_lines(std::string_view text, std::size_t width) {
  if (width == 0) return std::string(text);
  std::string out;
  std::size_t pos = 0;
  while (pos < text.size()) {
    const std::size_t nl = text.find('\n', pos);
    const std::size_t end = nl == std::string_view::npos ? text.size() : nl;
    const std::string_view line = text.substr(pos, end - pos);
    if (display_width(line) <= width) {
      out += line;
    } else {
      const std::size_t lead = std::min(line.find_first_not_of(' '), width / 2);
      const std::string first_indent(lead, ' '), next_indent(std::min(lead + 2, width / 2), ' ');
      const auto first = wrap_text(line.substr(lead), width - lead);
      // The first line at the line's own indent, the rest two further in.
      out += first_indent + first.front();
      std::string rest;
      for (std::size_t i = 1; i < first.size(); ++i) rest += (rest.empty() ? "" : " ") + first[i];
      if (!rest.empty())
        for (const auto& l : wrap_text(rest, width - next_indent.size())) out += "\n" + next_indent + l;
    }
    if (nl == std::string_view::npos) break;
    out += '\n';
    pos = nl + 1;
  }
  return out;
}

std::string Table::str(std::size_t max_width) const {
  const std::size_t n = header_.size();
  std::vector<std::size_t> width(n, 0), floor(n, 0);
  std::vector<bool> text_column(n, false);
  for (std::size_t c = 0; c < n; ++c) {
    width[c] = display_width(header_[c]);
    for (const auto& w : wrap_text(header_[c], 1)) floor[c] = std::max(floor[c], display_width(w));
  }
  for (const auto& r : rows_)
    for (std::size_t c = 0; c < r.size() && c < n; ++c) {
      width[c] = std::max(width[c], display_width(r[c]));
      if (!r[c].empty() && !numeric(r[c])) text_column[c] = true;
    }
  auto total_of = [&] {
    std::size_t t = n ? 2 * (n - 1) : 0;
    for (std::size_t w : width) t += w;
    return t;
  };
  // Too wide: narrow the widest text column one column at a time, down to its floor.
  if (max_width > 0)
    while (total_of() > max_width) {
      std::size_t widest = n;
      for (std::size_t c = 0; c < n; ++c) {
        const std::size_t lowest = std::max<std::size_t>(floor[c], std::min<std::size_t>(10, width[c]));
        if (text_column[c] && width[c] > lowest && (widest == n || width[c] > width[widest])) widest = c;
      }
      if (widest == n) break;  // every text column at its floor: the table stays wider
      --width[widest];
    }
  auto lines = [&](const std::vector<std::string>& r, bool head) {
    std::vector<std::vector<std::string>> cells(n);
    std::size_t height = 1;
    for (std::size_t c = 0; c < n; ++c) {
      const std::string cell = c < r.size() ? r[c] : "";
      cells[c] = display_width(cell) <= width[c] ? std::vector<std::string>{cell} : wrap_text(cell, width[c]);
      height = std::max(height, cells[c].size());
    }
    std::string s;
    for (std::size_t k = 0; k < height; ++k) {
      std::string l;
      for (std::size_t c = 0; c < n; ++c) {
        const std::string cell = k < cells[c].size() ? cells[c][k] : "";
        const std::size_t pad = width[c] - std::min(width[c], display_width(cell));
        const bool right = !head && cells[c].size() == 1 && numeric(cell);
        if (c) l += "  ";
        l += right ? std::string(pad, ' ') + cell : cell + (c + 1 < n ? std::string(pad, ' ') : "");
      }
      s += l + "\n";
    }
    return s;
  };
  std::string out = lines(header_, true);
  out += std::string(total_of(), '-') + "\n";
  for (const auto& r : rows_) out += lines(r, false);
  // Still wider (numbers are never cut, text columns stop at their floor): said, so that a
  // wrapped-around table on a narrow terminal is not taken for a broken one.
  if (max_width > 0 && total_of() > max_width)
    for (const auto& l : wrap_text("(this table is " + std::to_string(total_of()) + " columns wide, the terminal " +
                                       std::to_string(max_width) + ": its numbers are kept whole; a wider terminal, "
                                       "or a pipe, shows it unwrapped)",
                                   max_width))
      out += l + "\n";
  return out;
}

std::string fixed(double v, int digits) {
  if (std::isnan(v)) return "-";
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", digits, v);
  return buf;
}

std::string sig(double v) {
  if (!std::isfinite(v)) return "-";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.4g", v);
  return buf;
}

std::string pct(double ratio, int decimals) {
  return std::isfinite(ratio) ? fixed(100.0 * ratio, decimals) + "%" : "-";
}

}  // namespace fogbench::cli
