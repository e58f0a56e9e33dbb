// The rate limit of a repeating warning (daemon/src/repeat_log.hpp): "setpoint not written"
// logged once, then once per interval with its count, and the count of what was held back when
// the condition stops or changes; numbers in an error do not make it a new condition.
#include <catch2/catch.hpp>

#include "../../daemon/src/repeat_log.hpp"

using fogbench::daemon::repeat_key;
using fogbench::daemon::RepeatLog;
using namespace std::chrono_literals;

namespace {
const std::string kOff = "chamber: exception 4 (slave device failure) writing register 300";
std::string line(double sp_c) { return "setpoint " + std::to_string(sp_c) + " C not written: " + kOff; }
}  // namespace

TEST_CASE("a warning repeated every second for ten minutes is logged once a minute with its count", "[repeat_log]") {
  RepeatLog log(60s);
  const auto t0 = RepeatLog::Clock::time_point{} + 1000s;
  std::vector<std::string> logged;
  for (int s = 0; s < 600; ++s)
    for (auto& l : log.occurred(repeat_key(kOff), line(20.0 + 0.01 * s), t0 + std::chrono::seconds(s)))
      logged.push_back(l);
  // The first occurrence, then one line at 60 s, 120 s, ... 540 s: 1 + 9.
  REQUIRE(logged.size() == 10);
  CHECK(logged[0] == line(20.0));
  CHECK(logged[1].find("(repeated 60 times in the last 60 s)") != std::string::npos);
  CHECK(logged[1].starts_with(line(20.6)));  // the line as it is now, not as it was
  // 600 occurrences in all: 1 logged in full, 9 x 60 counted in the periodic lines, 59 held back.
  auto closing = log.cleared();
  REQUIRE(closing.size() == 1);
  CHECK(closing[0].find("(repeated 59 more times since the last line)") != std::string::npos);
  CHECK_FALSE(log.active());
}

TEST_CASE("a repeating warning that stops before its interval ends says how often it repeated", "[repeat_log]") {
  RepeatLog log(60s);
  const auto t0 = RepeatLog::Clock::time_point{};
  CHECK(log.occurred("k", "a", t0).size() == 1);
  CHECK(log.occurred("k", "a", t0 + 1s).empty());
  CHECK(log.occurred("k", "a", t0 + 2s).empty());
  auto closing = log.cleared();
  REQUIRE(closing.size() == 1);
  CHECK(closing[0] == "a (repeated 2 more times since the last line)");
  // A single occurrence that clears leaves nothing more to say; the next one is logged in full.
  CHECK(log.occurred("k", "b", t0 + 3s) == std::vector<std::string>{"b"});
  CHECK(log.cleared().empty());
  CHECK(log.cleared().empty());  // clearing twice is harmless
}

TEST_CASE("another error is logged at once, after the count of the one it replaces", "[repeat_log]") {
  RepeatLog log(60s);
  const auto t0 = RepeatLog::Clock::time_point{};
  (void)log.occurred("off", "off", t0);
  (void)log.occurred("off", "off", t0 + 1s);
  auto lines = log.occurred("lost", "link lost", t0 + 2s);
  REQUIRE(lines.size() == 2);
  CHECK(lines[0] == "off (repeated 1 more times since the last line)");
  CHECK(lines[1] == "link lost");
  CHECK(log.occurred("lost", "link lost", t0 + 3s).empty());
}

TEST_CASE("an error's numbers do not make it another condition, its words do", "[repeat_log]") {
  CHECK(repeat_key("setpoint 25.3 degC outside the configured limits -40..85 degC") ==
        repeat_key("setpoint 26 degC outside the configured limits -40..85 degC"));
  CHECK(repeat_key("TEMP, S25.3 answered NA:DATA OUT OF RANGE") == repeat_key("TEMP, S-1.5e-3 answered NA:DATA OUT OF RANGE"));
  CHECK(repeat_key("link lost") != repeat_key("link refused"));
  CHECK(repeat_key("register 300") == "register #");
  CHECK(repeat_key("") == "");
}

TEST_CASE("a set of repeating conditions: two alternating warnings are limited each, not logged at every change", "[repeat_log]") {
  using fogbench::daemon::RepeatLogSet;
  const std::string garbage = "/dev/ttyUSB0: 17 bytes of garbage before a sync word at byte 4096";
  const std::string crc = "/dev/ttyUSB0: frame at byte 8192: CRC 0x1a2b, computed 0x3c4d";
  RepeatLogSet set(60s);
  const auto t0 = RepeatLogSet::Clock::time_point{} + 1000s;
  std::vector<std::string> logged;
  // Ten minutes of a garbage run and a CRC error every second, alternating.
  for (int s = 0; s < 600; ++s)
    for (const auto& l : set.occurred(s % 2 ? crc : garbage, t0 + std::chrono::seconds(s))) logged.push_back(l);
  // Each condition: its first line, then one line a minute with its count (at 60, 120, ... 540
  // s of its own clock): 10 each. A single RepeatLog would have logged all 600 (a change of
  // condition every second).
  CHECK(logged.size() == 20);
  CHECK(set.conditions() == 2);
  CHECK(logged[0] == garbage);
  CHECK(logged[1] == crc);
  CHECK(logged[2].find("(repeated 30 times in the last 60 s)") != std::string::npos);

  // Ever-new shapes beyond the limit share one condition, so they are limited too.
  RepeatLogSet few(60s, 4);
  std::size_t lines = 0;
  for (int s = 0; s < 100; ++s)
    lines += few.occurred("message kind " + std::string(1, static_cast<char>('a' + s % 26)) + std::string(static_cast<std::size_t>(s / 26), '!'),
                          t0 + std::chrono::seconds(s))
                 .size();
  CHECK(few.conditions() == 5);  // 4 told apart, and "other"
  CHECK(lines <= 4 + 2 * 2);     // the 4 first lines; "other": its first and one a minute
}
