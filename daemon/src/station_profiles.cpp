// The profiles a station may run: by name from its profile directory, or from text, parsed and
// checked against the chamber's limits (station.hpp).
#include <algorithm>
#include <cmath>
#include <iomanip>
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

// The units ride the table: a rate beyond what a unit's counts carry at its scale would be stored
// as the int32 limit (a clipped rate, flagged out_of_range), and the scale factor fitted from
// those steps would be wrong. The first such step, by line and unit; empty when all fit.
std::string rate_beyond_unit_scales(const profiles::Profile& p, const std::vector<drivers::UnitConfig>& units) {
  for (const auto& r : p.rate_steps) {
    for (std::size_t i = 0; i < units.size(); ++i) {
      // The largest rate the unit's frames carry, deg/s: the int32 count limit at its scale.
      const double holds_dps = std::abs(units[i].gyro.mean_counts_to_rate_dph(2147483647.0)) / 3600.0;
      if (std::fabs(r.rate_dps) <= holds_dps) continue;
      std::ostringstream why;
      why << p.source_name << ":" << r.line << ":" << r.rate_column << ": '" << r.text << "': table rate " << r.rate_dps
          << " deg/s is beyond what units[" << i << "]'s gyro counts carry at its scale (int32 limit: +-"
          << std::setprecision(4) << holds_dps << " deg/s, units[" << i
          << "].gyro); a coarser scale or slower table rates (docs/scale-factor.md)";
      return why.str();
    }
  }
  return {};
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
  if (config_.rate_table) {
    if (auto ok = profiles::check_rate_limits(*p, config_.rate_table->limits.max_rate_dps); !ok)
      return api_error(ErrorCode::limits, ok.error().to_string() + " (rate_table.max_rate_dps)");
    if (auto why = rate_beyond_unit_scales(*p, config_.drivers.units); !why.empty())
      return api_error(ErrorCode::limits, why);
  }
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
