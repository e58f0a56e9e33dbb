// The one unknown-field check every file of fogbench shares (drivers/known_fields.hpp): its
// message form, its order, what it leaves to the caller.
#include <catch2/catch.hpp>

#include <nlohmann/json.hpp>

#include "fogbench/drivers/known_fields.hpp"

using fogbench::drivers::field_path;
using fogbench::drivers::unknown_field;
using nlohmann::json;

TEST_CASE("unknown_field: the field's path and the known fields in the order given") {
  const json j = {{"port", 7000}, {"tokn", "x"}};
  CHECK(unknown_field(j, "socket.tcp", {"port", "token"}) == "socket.tcp.tokn: unknown field (known: port, token)");
  // At the top level the field is its own path.
  CHECK(unknown_field(j, "", {"token", "port"}) == "tokn: unknown field (known: token, port)");
  // A path may carry where the object is; the field is joined to it as to any path.
  CHECK(unknown_field(j, "bench.json: units[0]", {"port"}) == "bench.json: units[0].tokn: unknown field (known: port)");
  CHECK(unknown_field(json{{"a", 1}}, "x", {}) == "x.a: unknown field (known: )");
}

TEST_CASE("unknown_field: nothing when every field is known, or for what is not an object") {
  CHECK_FALSE(unknown_field(json{{"port", 1}, {"token", "t"}}, "socket.tcp", {"port", "token"}).has_value());
  CHECK_FALSE(unknown_field(json::object(), "x", {}).has_value());
  // The caller names a wrong type in its own words; an array's elements are not fields.
  CHECK_FALSE(unknown_field(json::array({1, 2}), "x", {"port"}).has_value());
  CHECK_FALSE(unknown_field(json("text"), "x", {"port"}).has_value());
}

TEST_CASE("unknown_field: the first unknown field in the object's order is named") {
  // nlohmann::json keeps an object's keys sorted: "b" comes before "c" whatever the order written.
  const json j = json::parse(R"({"c": 1, "a": 2, "b": 3})");
  CHECK(unknown_field(j, "p", {"a"}) == "p.b: unknown field (known: a)");
}

TEST_CASE("field_path: joins with a dot, the top level alone") {
  CHECK(field_path("", "key") == "key");
  CHECK(field_path("a.b", "c") == "a.b.c");
  CHECK(field_path("units[1]", "gyro") == "units[1].gyro");
}
