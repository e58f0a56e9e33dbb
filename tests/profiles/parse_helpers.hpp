// Parsing a profile in a test: the profile, or the error it must give (with its text shown when
// a parse that should succeed fails).
#pragma once

#include <catch2/catch.hpp>

#include <string>
#include <string_view>

#include "fogbench/profiles/profile.hpp"

namespace fogbench::profiles::test {

inline Profile parse_ok(std::string_view text) {
  auto p = parse_profile(text, "t.profile");
  INFO((p ? std::string() : p.error().to_string()));
  REQUIRE(p.has_value());
  return *p;
}

inline ProfileError parse_err(std::string_view text) {
  auto p = parse_profile(text, "t.profile");
  REQUIRE_FALSE(p.has_value());
  return p.error();
}

}  // namespace fogbench::profiles::test
