// The line splitter: whole lines out of arbitrary byte chunks, and the 1 MiB limit.
#include <catch2/catch.hpp>

#include "fogbench/daemon/framing.hpp"

using fogbench::daemon::LineSplitter;
using Status = LineSplitter::Status;

TEST_CASE("framing: lines split across and within chunks") {
  LineSplitter s;
  std::string line;
  s.feed("{\"id\":1}\n{\"id\"");
  REQUIRE(s.next(line) == Status::line);
  CHECK(line == "{\"id\":1}");
  CHECK(s.next(line) == Status::incomplete);
  s.feed(":2}\r\n\n{\"id\":3}\n");
  REQUIRE(s.next(line) == Status::line);
  CHECK(line == "{\"id\":2}");  // the \r of a telnet-style client is dropped
  REQUIRE(s.next(line) == Status::line);
  CHECK(line.empty());          // an empty line is a line; the session skips it
  REQUIRE(s.next(line) == Status::line);
  CHECK(line == "{\"id\":3}");
  CHECK(s.next(line) == Status::incomplete);
  CHECK(s.buffered() == 0);
}

TEST_CASE("framing: one byte at a time") {
  LineSplitter s;
  const std::string text = "{\"cmd\":\"status\",\"id\":7}\n";
  std::string line;
  int lines = 0;
  for (char c : text) {
    s.feed(std::string_view(&c, 1));
    while (s.next(line) == Status::line) ++lines;
  }
  CHECK(lines == 1);
  CHECK(line == "{\"cmd\":\"status\",\"id\":7}");
}

TEST_CASE("framing: a line over the limit is reported, with or without its newline") {
  std::string line;
  SECTION("no newline yet") {
    LineSplitter s(16);
    s.feed(std::string(17, 'x'));
    CHECK(s.next(line) == Status::too_long);
    s.feed("\n{}\n");
    CHECK(s.next(line) == Status::too_long);  // spent: the connection is to be closed
  }
  SECTION("newline present") {
    LineSplitter s(16);
    s.feed(std::string(17, 'x') + "\n");
    CHECK(s.next(line) == Status::too_long);
  }
  SECTION("exactly at the limit is fine") {
    LineSplitter s(16);
    s.feed(std::string(16, 'x') + "\n");
    CHECK(s.next(line) == Status::line);
    CHECK(line.size() == 16);
  }
}
