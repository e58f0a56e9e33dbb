// What fogctl's commands share about their options: checks that CLI11 does not make (a seed is
// not negative, a run id is a positive integer) and the translation of the model's internal
// names in its messages (ar_order) into the options the user typed (--ar-order).
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include <CLI/CLI.hpp>

namespace fogbench::cli {

// Refuses a negative seed (CLI11 would wrap -1 to 18446744073709551615).
CLI::Validator seed_check();

// A stored run's id as given to `option` (e.g. "--run"): a positive integer, else a
// CLI::ValidationError naming the value and, for a file name, the way to use it (thrown from an
// option's each(), which CLI11 reports as "OPTION: message").
std::int64_t parse_run_id(const std::string& option, const std::string& value);

// The message with the model's field names replaced by the options that set them, e.g.
// {"ar_order", "--ar-order"}: "ar_order must be 1..10" -> "--ar-order must be 1..10". Whole
// words only (max_lag_s is not touched inside max_lag_s_x).
std::string as_typed(std::string message, const std::vector<std::pair<std::string, std::string>>& names);

}  // namespace fogbench::cli
