// A warning that repeats (a chamber that is switched off refuses every second's setpoint) is
// logged once when it starts, then at most once per interval with how many times it repeated
// meanwhile, and once more when it stops or changes: a line per minute instead of one per
// second, and the count says what the silence hid (issue 28, "log lines rate-limited").
//
// Pure bookkeeping: it returns the lines to log and the caller logs them, so the rule is tested
// without a logger or a clock (tests/daemon/repeat_log_test.cpp).
#pragma once

#include <chrono>
#include <cstdint>
#include <map>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace fogbench::daemon {

// The shape of an error message: every number in it (a setpoint that follows a ramp, a command
// that carries it) masked as '#', so that "setpoint 25.3 refused" and "setpoint 25.4 refused"
// are one repeating condition and "link lost" another.
inline std::string repeat_key(std::string_view message) {
  const auto digit = [&](std::size_t i) { return i < message.size() && message[i] >= '0' && message[i] <= '9'; };
  std::string key;
  key.reserve(message.size());
  bool in_number = false;
  for (std::size_t i = 0; i < message.size(); ++i) {
    const char c = message[i];
    const bool sign = (c == '-' || c == '+') && digit(i + 1);  // -1.5, or 1e-3's exponent
    if (digit(i) || sign || (in_number && (c == '.' || c == 'e' || c == 'E'))) {
      if (!in_number) key.push_back('#');
      in_number = true;
      continue;
    }
    in_number = false;
    key.push_back(c);
  }
  return key;
}

class RepeatLog {
 public:
  using Clock = std::chrono::steady_clock;

  // interval: the least wall time between two lines of one repeating condition.
  explicit RepeatLog(std::chrono::seconds interval = std::chrono::seconds(60)) : interval_(interval) {}

  // The condition `key` happened now; `line` is its full log line (it may carry a value that
  // changes from one time to the next, as the setpoint does in a ramp: only `key` is compared).
  // Returns the lines to log now, in order: none while a repeat is held back, the line itself
  // the first time, "<line> (repeated N times in the last S s)" once the interval is over, and
  // when the key changes, the old condition's count of held-back repeats before the new line.
  std::vector<std::string> occurred(const std::string& key, const std::string& line, Clock::time_point now) {
    std::vector<std::string> out;
    if (active_ && key != key_) {
      if (held_ > 0) out.push_back(summary());
      active_ = false;
    }
    if (!active_) {
      active_ = true;
      key_ = key;
      held_ = 0;
      since_ = now;
      out.push_back(line);
      return out;
    }
    ++held_;
    last_line_ = line;
    if (now - since_ >= interval_) {
      out.push_back(line + " (repeated " + std::to_string(held_) + " times in the last " +
                    std::to_string(std::chrono::duration_cast<std::chrono::seconds>(now - since_).count()) +
                    " s)");
      held_ = 0;
      since_ = now;
    }
    return out;
  }

  // The condition is over (the setpoint was written): the count of repeats held back since the
  // last line, if any, so the log does not end on a line that under-counts.
  std::vector<std::string> cleared() {
    std::vector<std::string> out;
    if (active_ && held_ > 0) out.push_back(summary());
    active_ = false;
    held_ = 0;
    return out;
  }

  bool active() const { return active_; }

 private:
  std::string summary() const {
    return last_line_ + " (repeated " + std::to_string(held_) + " more times since the last line)";
  }

  std::chrono::seconds interval_;
  bool active_ = false;
  std::string key_;
  std::string last_line_;
  std::int64_t held_ = 0;      // repeats since the last line logged
  Clock::time_point since_{};  // when the last line was logged
};

// Several repeating conditions at once, each by its shape (repeat_key) on its own RepeatLog: a
// serial gyro's line that alternates garbage and CRC errors is two conditions each limited to
// a line per interval, not a change of condition every second (which RepeatLog would log each
// time). At most `max_conditions` shapes are told apart; the rest share one "other" condition,
// so a stream of ever-new messages is still limited.
class RepeatLogSet {
 public:
  using Clock = RepeatLog::Clock;

  explicit RepeatLogSet(std::chrono::seconds interval = std::chrono::seconds(60), std::size_t max_conditions = 32)
      : interval_(interval), max_conditions_(max_conditions) {}

  // `line` happened now: the lines to log (and to record) now, as RepeatLog::occurred.
  std::vector<std::string> occurred(const std::string& line, Clock::time_point now) {
    std::string key = repeat_key(line);
    auto it = logs_.find(key);
    if (it == logs_.end()) {
      if (logs_.size() >= max_conditions_) key = "(other)";
      it = logs_.try_emplace(key, interval_).first;
    }
    return it->second.occurred(key, line, now);
  }

  std::size_t conditions() const { return logs_.size(); }

 private:
  std::chrono::seconds interval_;
  std::size_t max_conditions_;
  std::map<std::string, RepeatLog> logs_;
};

}  // namespace fogbench::daemon
