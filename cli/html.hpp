// HTML escaping for the pages fogctl writes (report, certificate, plan report, fleet report).
#pragma once

#include <string>
#include <string_view>
#include <vector>

namespace fogbench::cli {

// Text made safe inside an element or a double-quoted attribute: & < > " escaped.
inline std::string html_escape(std::string_view s) {
  std::string o;
  o.reserve(s.size());
  for (char c : s) {
    switch (c) {
      case '&': o += "&amp;"; break;
      case '<': o += "&lt;"; break;
      case '>': o += "&gt;"; break;
      case '"': o += "&quot;"; break;
      default: o += c;
    }
  }
  return o;
}

// A table of a page: a head row, then rows; words align left, numbers right (class "w" marks
// a word cell for the page's style). Cells are escaped.
struct HtmlTable {
  std::string s = "<table>";
  explicit HtmlTable(const std::vector<std::string>& head) {
    s += "<tr>";
    for (const auto& h : head) s += "<th>" + html_escape(h) + "</th>";
    s += "</tr>";
  }
  void row(const std::vector<std::string>& cells, const std::string& cls = "") {
    s += cls.empty() ? "<tr>" : "<tr class=\"" + cls + "\">";
    // Words align left, numbers right (so that digits line up).
    for (const auto& c : cells) {
      const bool num = !c.empty() && c.find_first_not_of("0123456789+-.e%<> →") == std::string::npos;
      s += num ? "<td>" + html_escape(c) + "</td>" : "<td class=\"w\">" + html_escape(c) + "</td>";
    }
    s += "</tr>";
  }
  std::string str() const { return s + "</table>"; }
};

}  // namespace fogbench::cli
