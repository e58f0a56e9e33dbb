// Typed JSON field access with field-path errors, shared by the map and configuration parsers.
#include "json_fields.hpp"

#include <cmath>

#include "fogbench/drivers/known_fields.hpp"

namespace fogbench::drivers {

std::string field_path(std::string_view path, std::string_view key) {
  std::string out(path);
  if (!out.empty()) out += '.';
  out += key;
  return out;
}

std::optional<std::string> unknown_field(const nlohmann::json& object, std::string_view path,
                                         std::span<const std::string_view> known) {
  if (!object.is_object()) return std::nullopt;
  for (auto it = object.begin(); it != object.end(); ++it) {
    bool ok = false;
    for (auto k : known) ok = ok || it.key() == k;
    if (ok) continue;
    std::string list;
    for (auto k : known) {
      if (!list.empty()) list += ", ";
      list += k;
    }
    return field_path(path, it.key()) + ": unknown field (known: " + list + ")";
  }
  return std::nullopt;
}

std::optional<std::string> unknown_field(const nlohmann::json& object, std::string_view path,
                                         std::initializer_list<std::string_view> known) {
  return unknown_field(object, path, std::span<const std::string_view>(known.begin(), known.size()));
}

}  // namespace fogbench::drivers

namespace fogbench::drivers::detail {
namespace {

const char* kind_of(const json& v) {
  switch (v.type()) {
    case json::value_t::null: return "null";
    case json::value_t::object: return "an object";
    case json::value_t::array: return "an array";
    case json::value_t::string: return "a string";
    case json::value_t::boolean: return "a boolean";
    case json::value_t::number_integer:
    case json::value_t::number_unsigned: return "an integer";
    case json::value_t::number_float: return "a number";
    default: return "something else";
  }
}

std::string int_expectation(std::int64_t min, std::int64_t max) {
  return "expected an integer " + std::to_string(min) + ".." + std::to_string(max);
}

Result<std::int64_t> as_int(const json& v, const std::string& path, std::int64_t min,
                            std::int64_t max) {
  std::optional<std::int64_t> n;
  if (v.is_number_unsigned()) {
    const auto u = v.get<std::uint64_t>();
    if (u <= static_cast<std::uint64_t>(INT64_MAX)) n = static_cast<std::int64_t>(u);
  } else if (v.is_number_integer()) {
    n = v.get<std::int64_t>();
  } else if (v.is_number_float()) {
    // 1e6 in a file is an integer to a person: accept floats with no fractional part.
    const double d = v.get<double>();
    if (std::isfinite(d) && std::floor(d) == d && std::fabs(d) < 9.0e15) {
      n = static_cast<std::int64_t>(d);
    }
  }
  if (!n || *n < min || *n > max) {
    std::string got = v.is_number() ? v.dump() : std::string(kind_of(v));
    return config_error(path, int_expectation(min, max) + " (got " + got + ")");
  }
  return *n;
}

}  // namespace

std::string join_path(const std::string& base, std::string_view key) { return field_path(base, key); }

std::string index_path(const std::string& base, std::size_t index) {
  return base + "[" + std::to_string(index) + "]";
}

std::unexpected<DriverError> config_error(const std::string& path, std::string what) {
  return fail(ErrorCode::config, (path.empty() ? std::string("(top level)") : path) + ": " + what);
}

Result<void> expect_object(const json& value, const std::string& path) {
  if (!value.is_object()) {
    return config_error(path, std::string("expected an object (got ") + kind_of(value) + ")");
  }
  return {};
}

Result<void> expect_known_keys(const json& object, const std::string& path,
                               std::initializer_list<std::string_view> known) {
  return expect_known_keys(object, path, std::span<const std::string_view>(known.begin(), known.size()));
}

Result<void> expect_known_keys(const json& object, const std::string& path,
                               std::span<const std::string_view> known) {
  if (auto refusal = unknown_field(object, path, known)) return fail(ErrorCode::config, std::move(*refusal));
  return {};
}

Result<std::int64_t> get_int(const json& object, const std::string& path, std::string_view key,
                             std::int64_t min, std::int64_t max) {
  const auto field = join_path(path, key);
  auto it = object.find(key);
  if (it == object.end()) return config_error(field, "missing (" + int_expectation(min, max) + ")");
  return as_int(*it, field, min, max);
}

Result<std::int64_t> get_int_or(const json& object, const std::string& path, std::string_view key,
                                std::int64_t min, std::int64_t max, std::int64_t fallback) {
  auto it = object.find(key);
  if (it == object.end()) return fallback;
  return as_int(*it, join_path(path, key), min, max);
}

Result<double> get_number(const json& object, const std::string& path, std::string_view key) {
  const auto field = join_path(path, key);
  auto it = object.find(key);
  if (it == object.end()) return config_error(field, "missing (expected a number)");
  if (!it->is_number() || !std::isfinite(it->get<double>())) {
    return config_error(field, std::string("expected a finite number (got ") + kind_of(*it) + ")");
  }
  return it->get<double>();
}

Result<double> get_number_or(const json& object, const std::string& path, std::string_view key,
                             double fallback) {
  if (!object.contains(key)) return fallback;
  return get_number(object, path, key);
}

Result<std::string> get_string(const json& object, const std::string& path,
                               std::string_view key) {
  const auto field = join_path(path, key);
  auto it = object.find(key);
  if (it == object.end()) return config_error(field, "missing (expected a string)");
  if (!it->is_string()) {
    return config_error(field, std::string("expected a string (got ") + kind_of(*it) + ")");
  }
  return it->get<std::string>();
}

Result<std::string> get_string_or(const json& object, const std::string& path,
                                  std::string_view key, std::string fallback) {
  if (!object.contains(key)) return fallback;
  return get_string(object, path, key);
}

Result<Range> get_range_or(const json& object, const std::string& path, std::string_view key,
                           Range fallback) {
  auto it = object.find(key);
  if (it == object.end()) return fallback;
  const auto field = join_path(path, key);
  if (auto ok = expect_object(*it, field); !ok) return std::unexpected(ok.error());
  if (auto ok = expect_known_keys(*it, field, {"min", "max"}); !ok) {
    return std::unexpected(ok.error());
  }
  auto lo = get_number(*it, field, "min");
  if (!lo) return std::unexpected(lo.error());
  auto hi = get_number(*it, field, "max");
  if (!hi) return std::unexpected(hi.error());
  if (!(*lo < *hi)) {
    return config_error(field, "min (" + format_number(*lo) + ") must be below max (" +
                                   format_number(*hi) + ")");
  }
  return Range{*lo, *hi};
}

}  // namespace fogbench::drivers::detail
