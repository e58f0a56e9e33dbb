// Reading typed fields out of nlohmann::json with errors that name the field path
// ("units[1].gyro.node_id: expected an integer 1..2047"). Internal to the drivers.
#pragma once

#include <nlohmann/json.hpp>

#include <cstdint>
#include <initializer_list>
#include <optional>
#include <span>
#include <string>
#include <string_view>

#include "fogbench/drivers/error.hpp"

namespace fogbench::drivers::detail {

using nlohmann::json;

std::string join_path(const std::string& base, std::string_view key);
std::string index_path(const std::string& base, std::size_t index);

std::unexpected<DriverError> config_error(const std::string& path, std::string what);

Result<void> expect_object(const json& value, const std::string& path);
// Refuses a key that is not in `known`, so a typo ("scael") is an error and not a silent default.
Result<void> expect_known_keys(const json& object, const std::string& path,
                               std::initializer_list<std::string_view> known);
Result<void> expect_known_keys(const json& object, const std::string& path,
                               std::span<const std::string_view> known);

// Required fields: missing or wrongly typed is an error naming `path.key`.
Result<std::int64_t> get_int(const json& object, const std::string& path, std::string_view key,
                             std::int64_t min, std::int64_t max);
Result<double> get_number(const json& object, const std::string& path, std::string_view key);
Result<std::string> get_string(const json& object, const std::string& path, std::string_view key);

// Optional fields: absent gives the fallback, present but wrong is still an error.
Result<std::int64_t> get_int_or(const json& object, const std::string& path, std::string_view key,
                                std::int64_t min, std::int64_t max, std::int64_t fallback);
Result<double> get_number_or(const json& object, const std::string& path, std::string_view key,
                             double fallback);
Result<std::string> get_string_or(const json& object, const std::string& path,
                                  std::string_view key, std::string fallback);

// A {"min": x, "max": y} object with min < max.
struct Range {
  double min = 0;
  double max = 0;
};
Result<Range> get_range_or(const json& object, const std::string& path, std::string_view key,
                           Range fallback);

}  // namespace fogbench::drivers::detail
