// Other CSV dialects rewritten into fogbench's own (csv_dialect.hpp).
#include "csv_dialect.hpp"

#include <vector>

namespace fogbench::storage::detail {

namespace {

bool blank_or_comment(std::string_view line) {
  for (char c : line) {
    if (c == ' ' || c == '\t' || c == '\r') continue;
    return c == '#';
  }
  return true;
}

// The fields of a line split at `delimiter` outside double quotes; quoted fields are kept with
// their quotes (the plain parser unquotes them).
std::vector<std::string_view> split(std::string_view line, char delimiter) {
  std::vector<std::string_view> out;
  bool quoted = false;
  std::size_t start = 0;
  for (std::size_t i = 0; i < line.size(); ++i) {
    if (line[i] == '"') quoted = !quoted;
    else if (line[i] == delimiter && !quoted) {
      out.push_back(line.substr(start, i - start));
      start = i + 1;
    }
  }
  out.push_back(line.substr(start));
  return out;
}

}  // namespace

char detect_delimiter(std::string_view text) {
  if (text.starts_with("\xEF\xBB\xBF")) text.remove_prefix(3);
  std::size_t pos = 0;
  while (pos < text.size()) {
    std::size_t nl = text.find('\n', pos);
    if (nl == std::string_view::npos) nl = text.size();
    const std::string_view line = text.substr(pos, nl - pos);
    pos = nl + 1;
    if (blank_or_comment(line)) continue;
    std::size_t commas = 0, semicolons = 0, tabs = 0;
    bool quoted = false;
    for (char c : line) {
      if (c == '"') quoted = !quoted;
      if (quoted) continue;
      commas += c == ',';
      semicolons += c == ';';
      tabs += c == '\t';
    }
    if (commas == 0 && semicolons > 0) return ';';
    if (commas == 0 && semicolons == 0 && tabs > 0) return '\t';
    return ',';
  }
  return ',';
}

std::string to_plain_csv(std::string_view text, char delimiter, bool decimal_comma) {
  std::string out;
  out.reserve(text.size() + text.size() / 16);
  if (text.starts_with("\xEF\xBB\xBF")) text.remove_prefix(3);
  bool header = true;
  std::size_t pos = 0;
  while (pos < text.size()) {
    std::size_t nl = text.find('\n', pos);
    const bool last = nl == std::string_view::npos;
    if (last) nl = text.size();
    std::string_view line = text.substr(pos, nl - pos);
    pos = nl + 1;
    const bool cr = !line.empty() && line.back() == '\r';
    if (cr) line.remove_suffix(1);
    if (blank_or_comment(line)) {
      out += line;
    } else {
      const auto fields = split(line, delimiter);
      for (std::size_t i = 0; i < fields.size(); ++i) {
        if (i) out += ',';
        std::string_view f = fields[i];
        // Leading and trailing blanks are not part of a cell (the plain parser trims them too),
        // and a tab is a blank only when it is not the separator.
        while (!f.empty() && (f.front() == ' ' || (f.front() == '\t' && delimiter != '\t'))) f.remove_prefix(1);
        while (!f.empty() && (f.back() == ' ' || (f.back() == '\t' && delimiter != '\t'))) f.remove_suffix(1);
        if (f.size() >= 2 && f.front() == '"' && f.back() == '"') {
          out += f;
          continue;
        }
        std::string cell(f);
        if (decimal_comma && !header)
          for (char& c : cell)
            if (c == ',') c = '.';
        if (cell.find(',') != std::string::npos || cell.find('"') != std::string::npos) {
          std::string q = "\"";
          for (char c : cell) {
            if (c == '"') q += '"';
            q += c;
          }
          out += q + '"';
        } else {
          out += cell;
        }
      }
      header = false;
    }
    if (cr) out += '\r';
    if (!last) out += '\n';
  }
  return out;
}

}  // namespace fogbench::storage::detail
