// HTML escaping for the pages fogctl writes (report, certificate, plan report, fleet report).
#pragma once

#include <string>
#include <string_view>

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

}  // namespace fogbench::cli
