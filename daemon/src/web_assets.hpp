// The web panel's files, embedded in fogbenchd at build time (daemon/web/embed.cmake generates
// web_assets.cpp from daemon/web/ and the report's vendored uPlot), so the daemon serves them
// without any file on disk.
#pragma once

#include <string_view>

namespace fogbench::daemon::web {

struct Asset {
  std::string_view path;          // "/index.html"
  std::string_view content_type;  // "text/html; charset=utf-8"
  std::string_view body;
};

// The asset served at `path`, or nullptr.
const Asset* find_asset(std::string_view path);

}  // namespace fogbench::daemon::web
