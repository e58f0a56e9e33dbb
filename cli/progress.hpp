// Progress of a long command (run start --wait, run watch, simulate) on stderr: redrawn in place
// with '\r' only when the stream is a terminal; in a file or a pipe one line per phase change and
// one a minute, so that a log of a day's run stays a few hundred lines, not megabytes of redraws.
#pragma once

#include <chrono>
#include <functional>
#include <ostream>
#include <string>

namespace fogbench::cli {

// Whether progress on stderr is redrawn: stderr is a terminal (isatty). FOGCTL_PROGRESS=lines or
// =redraw overrides the guess (a terminal multiplexer that logs, a test).
bool progress_redraws();
// FOGCTL_PROGRESS=lines: progress lines asked for, from a command's start (a log that wants
// them all; without it a command that prints progress only when it runs long waits first).
bool progress_lines_asked();
// The width of the terminal progress is redrawn on: $COLUMNS when exported (at least 20), else
// stderr's terminal width, else 0 (unknown).
std::size_t progress_width();

class Progress {
 public:
  using Clock = std::function<std::chrono::steady_clock::time_point()>;
  // `redraw`: a terminal (progress_redraws()). `every`: the interval of the lines written when
  // not redrawing, s. `clock` is injected so that tests need no waiting.
  Progress(std::ostream& err, bool redraw, double every_s = 60.0, Clock clock = {});
  ~Progress();
  Progress(const Progress&) = delete;
  Progress& operator=(const Progress&) = delete;

  // The status now: `phase` names the stretch it is in (a line of its own when it changes),
  // `text` the full status line.
  void update(const std::string& phase, const std::string& text);
  // A message on a line of its own (ends a redrawn line first).
  void line(const std::string& text);
  // Ends the redrawn line (nothing when lines were written).
  void finish();
  // The terminal's width in columns (0: unknown, lines whole). A redrawn line longer than the
  // width less one is cut and ends with "...": a line that wrapped would scroll at every
  // redraw (issue 28). Lines written when not redrawing stay whole.
  void set_width(std::size_t columns) { width_ = columns; }
  std::size_t width() const { return redraw_ ? width_ : 0; }

 private:
  std::chrono::steady_clock::time_point now() const;

  std::ostream& err_;
  bool redraw_;
  std::chrono::duration<double> every_;
  Clock clock_;
  std::string phase_;
  bool started_ = false;
  bool open_line_ = false;  // a redrawn line is on screen, not ended by a newline
  std::size_t drawn_width_ = 0;
  std::size_t width_ = 0;
  std::chrono::steady_clock::time_point last_{};
};

// Progress of a command that is quick on a day's run and not on a week's (verify): nothing until
// it has run quiet_s (half a second on a terminal, 2 s in a file or a pipe, none with
// FOGCTL_PROGRESS=lines), then as Progress, so that a quick command prints nothing.
class QuietStartProgress {
 public:
  explicit QuietStartProgress(std::ostream& err);
  void update(const std::string& phase, const std::string& text);
  void finish() { bar_.finish(); }

 private:
  Progress bar_;
  std::chrono::steady_clock::time_point t0_;
  double quiet_s_;
};

}  // namespace fogbench::cli
