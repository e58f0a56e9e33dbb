// Checks and names of fogctl's options (options.hpp).
#include "options.hpp"

#include <charconv>
#include <filesystem>

namespace fogbench::cli {

CLI::Validator seed_check() {
  return CLI::Validator(
      [](std::string& v) -> std::string {
        if (!v.empty() && v.front() == '-') return "a seed is 0 or more, got " + v;
        return {};
      },
      "SEED");
}

std::int64_t parse_run_id(const std::string& option, const std::string& value) {
  std::int64_t id = 0;
  const char* end = value.data() + value.size();
  const auto [p, ec] = std::from_chars(value.data(), end, id);
  if (ec == std::errc{} && p == end && id > 0) return id;
  std::string why = "'" + value + "' is not a run id (a positive integer, as `fogctl run list` shows)";
  if (ec == std::errc::result_out_of_range) why = "'" + value + "' is out of the range of a run id";
  std::error_code fs_ec;
  if (std::filesystem::exists(value, fs_ec) || value.ends_with(".csv"))
    why += "; a CSV file is given without " + option;
  throw CLI::ValidationError(why);  // CLI11 puts the option's name before it (each() is a validator)
}

std::string as_typed(std::string message, const std::vector<std::pair<std::string, std::string>>& names) {
  auto word = [](char c) { return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_'; };
  for (const auto& [internal, typed] : names) {
    std::size_t p = 0;
    while ((p = message.find(internal, p)) != std::string::npos) {
      const std::size_t e = p + internal.size();
      if ((p > 0 && word(message[p - 1])) || (e < message.size() && word(message[e]))) {
        p = e;
        continue;
      }
      message.replace(p, internal.size(), typed);
      p += typed.size();
    }
  }
  return message;
}

}  // namespace fogbench::cli
