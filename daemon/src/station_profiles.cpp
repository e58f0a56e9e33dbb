// The profiles a station may run: by name from its profile directory, or from text, parsed and
// checked against the chamber's limits (station.hpp).
#include <algorithm>
#include <fstream>
#include <regex>
#include <sstream>

#include "fogbench/daemon/station.hpp"

namespace fogbench::daemon {

namespace {

bool valid_profile_name(const std::string& name) {
  static const std::regex re("[A-Za-z0-9_][A-Za-z0-9_.-]{0,63}");
  return std::regex_match(name, re);
}

}  // namespace

std::vector<std::string> Station::profile_names() const {
  std::vector<std::string> names;
  std::error_code ec;
  for (const auto& e : std::filesystem::directory_iterator(config_.profile_dir, ec)) {
    if (e.path().extension() == ".profile") names.push_back(e.path().stem().string());
  }
  std::sort(names.begin(), names.end());
  return names;
}

ApiResult<profiles::Profile> Station::check_profile_text(const std::string& text,
                                                         const std::string& source) const {
  auto p = profiles::parse_profile(text, source);
  if (!p) return api_error(ErrorCode::invalid_profile, p.error().to_string());
  // Rate steps drive the configured rate table. Without one, running the profile would run its
  // temperatures without its rates, a run other than the one written: refused by line.
  if (!p->rate_steps.empty() && !config_.rate_table) {
    const auto& r = p->rate_steps.front();
    return api_error(ErrorCode::invalid_profile,
                     source + ":" + std::to_string(r.line) + ":" + std::to_string(r.rate_column) + ": '" + r.text +
                         "': rate steps need a rate table, and no rate table is configured (rate_table, "
                         "docs/configuration.md); remove the " +
                         std::to_string(p->rate_steps.size()) + " rate line(s) to run the temperatures alone");
  }
  if (config_.rate_table)
    if (auto ok = profiles::check_rate_limits(*p, config_.rate_table->limits.max_rate_dps); !ok)
      return api_error(ErrorCode::limits, ok.error().to_string() + " (rate_table.max_rate_dps)");
  if (auto ok = profiles::check_limits(*p, config_.limits); !ok)
    return api_error(ErrorCode::limits, ok.error().to_string());
  return std::move(*p);
}

ApiResult<profiles::Profile> Station::load_profile(const std::string& name, std::string* text) const {
  if (!valid_profile_name(name))
    return api_error(ErrorCode::bad_request, "profile: expected a name of letters, digits, '_', '-' or '.'");
  const auto path = config_.profile_dir / (name + ".profile");
  std::ifstream in(path);
  if (!in) return api_error(ErrorCode::not_found, "profile " + name + ": not in " + config_.profile_dir.string());
  std::stringstream ss;
  ss << in.rdbuf();
  auto p = check_profile_text(ss.str(), name + ".profile");
  if (p && text) *text = ss.str();
  return p;
}

}  // namespace fogbench::daemon
