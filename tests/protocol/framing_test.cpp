// The line splitter: whole lines out of arbitrary byte chunks, and the 1 MiB limit.
#include <catch2/catch.hpp>

#include "fogbench/protocol/framing.hpp"

using fogbench::protocol::LineSplitter;
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

// --- parse_line: the limits checked while a request line is parsed (docs/protocol.md)

using fogbench::protocol::kMaxDepth;
using fogbench::protocol::parse_line;

namespace {
// `{"id":1,"cmd":"status","x":` + n '[' + n ']' + `}`: issue 11's crash line at n = 100,000.
std::string nested_request(std::size_t n) {
  return R"({"id":1,"cmd":"status","x":)" + std::string(n, '[') + std::string(n, ']') + "}";
}
}  // namespace

TEST_CASE("framing: parse_line takes a request nested up to the limit") {
  // The request object is level 1, so kMaxDepth - 1 arrays inside it reach the limit exactly.
  auto r = parse_line(nested_request(kMaxDepth - 1));
  REQUIRE(r.has_value());
  CHECK((*r)["cmd"] == "status");
  std::size_t depth = 1;
  for (const nlohmann::json* v = &(*r)["x"]; v->is_array(); v = v->empty() ? nullptr : &(*v)[0]) {
    ++depth;
    if (v->empty()) break;
  }
  CHECK(depth == kMaxDepth);
}

TEST_CASE("framing: parse_line refuses one level past the limit, naming depth and column") {
  auto r = parse_line(nested_request(kMaxDepth));
  REQUIRE(!r.has_value());
  // The prefix {"id":1,"cmd":"status","x": is 27 characters; the request's '{' is level 1, the
  // k-th '[' level k + 1, so level kMaxDepth + 1 opens at the kMaxDepth-th '[': column 27 + 64.
  CHECK(r.error() == "nesting deeper than 64 levels at column " + std::to_string(27 + kMaxDepth));
  // Brackets inside strings are not levels.
  const std::string quoted = R"({"id":1,"cmd":"status","s":")" + std::string(1000, '[') + R"("})";
  CHECK(parse_line(quoted).has_value());
}

TEST_CASE("framing: parse_line refuses issue 11's crash line without building it") {
  // 200 KB, under the 1 MiB line limit; before the limit this overflowed the stack in a
  // recursive copy (and destruction) of the parsed request.
  const std::string line = nested_request(100000);
  REQUIRE(line.size() < fogbench::protocol::kMaxLineBytes);
  auto r = parse_line(line);
  REQUIRE(!r.has_value());
  CHECK(r.error().starts_with("nesting deeper than 64 levels"));
  // The same with objects, and with nothing closed.
  std::string objects;
  for (int i = 0; i < 100000; ++i) objects += R"({"a":)";
  CHECK(!parse_line(objects).has_value());
  CHECK(!parse_line(std::string(100000, '[')).has_value());
}

TEST_CASE("framing: parse_line refuses a key twice in one object, at any depth") {
  auto top = parse_line(R"({"id":1,"cmd":"status","cmd":"run.abort"})");
  REQUIRE(!top.has_value());
  CHECK(top.error() == R"(duplicate key "cmd")");
  auto deep = parse_line(R"({"id":1,"cmd":"run.start","x":{"y":[{"k":1,"k":2}]}})");
  REQUIRE(!deep.has_value());
  CHECK(deep.error() == R"(duplicate key "k" in "x"."y")");
  // The same key in sibling objects is no duplicate; nor are keys that differ only in case.
  CHECK(parse_line(R"({"id":1,"a":{"k":1},"b":{"k":2},"K":3,"k":4})").has_value());
  CHECK(parse_line("{not json").error() == "not a JSON value");
}
