// Progress lines: redrawn on a terminal, plain lines elsewhere (progress.hpp).
#include "progress.hpp"

#include <sys/ioctl.h>
#include <unistd.h>

#include <cstdlib>
#include <cstring>

namespace fogbench::cli {

bool progress_redraws() {
  if (const char* p = std::getenv("FOGCTL_PROGRESS"); p && *p) {
    if (std::strcmp(p, "lines") == 0) return false;
    if (std::strcmp(p, "redraw") == 0) return true;
  }
  return ::isatty(STDERR_FILENO) == 1;
}

bool progress_lines_asked() {
  const char* p = std::getenv("FOGCTL_PROGRESS");
  return p && std::strcmp(p, "lines") == 0;
}

std::size_t progress_width() {
  if (const char* c = std::getenv("COLUMNS"); c && *c) {
    char* end = nullptr;
    const long n = std::strtol(c, &end, 10);
    if (end && *end == '\0' && n >= 20 && n <= 10000) return static_cast<std::size_t>(n);
  }
  winsize ws{};
  if (::ioctl(STDERR_FILENO, TIOCGWINSZ, &ws) == 0 && ws.ws_col >= 20) return ws.ws_col;
  return 0;
}

Progress::Progress(std::ostream& err, bool redraw, double every_s, Clock clock)
    : err_(err), redraw_(redraw), every_(every_s), clock_(std::move(clock)) {}

Progress::~Progress() { finish(); }

std::chrono::steady_clock::time_point Progress::now() const {
  return clock_ ? clock_() : std::chrono::steady_clock::now();
}

void Progress::update(const std::string& phase, const std::string& text) {
  const auto t = now();
  if (redraw_) {
    // A screen redraw five times a second at most; a new phase at once.
    if (started_ && phase == phase_ && t - last_ < std::chrono::milliseconds(200)) return;
    std::string shown = text;
    // One column short of the width: a line that fills the last column wraps on some terminals.
    if (width_ >= 20 && shown.size() > width_ - 1) shown = shown.substr(0, width_ - 4) + "...";
    std::string pad;
    if (shown.size() < drawn_width_) pad.assign(drawn_width_ - shown.size(), ' ');
    err_ << '\r' << shown << pad << std::flush;
    drawn_width_ = shown.size();
    open_line_ = true;
  } else {
    if (started_ && phase == phase_ && t - last_ < every_) return;
    err_ << text << '\n' << std::flush;
  }
  started_ = true;
  phase_ = phase;
  last_ = t;
}

void Progress::line(const std::string& text) {
  if (open_line_) err_ << '\n';
  open_line_ = false;
  drawn_width_ = 0;
  err_ << text << '\n' << std::flush;
}

void Progress::finish() {
  if (open_line_) err_ << '\n' << std::flush;
  open_line_ = false;
  drawn_width_ = 0;
}

QuietStartProgress::QuietStartProgress(std::ostream& err)
    : bar_(err, progress_redraws()),
      t0_(std::chrono::steady_clock::now()),
      quiet_s_(progress_lines_asked() ? 0.0 : progress_redraws() ? 0.5 : 2.0) {
  bar_.set_width(progress_width());
}

void QuietStartProgress::update(const std::string& phase, const std::string& text) {
  if (std::chrono::duration<double>(std::chrono::steady_clock::now() - t0_).count() < quiet_s_) return;
  bar_.update(phase, text);
}

}  // namespace fogbench::cli
