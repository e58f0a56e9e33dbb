// A run's audit trail in words for `fogctl run get` (its JSON stays for --json).
#include <algorithm>
#include <cmath>

#include "client_commands.hpp"

namespace fogbench::cli::commands {

using nlohmann::json;

namespace {

std::string value_text(const json& v) {
  if (v.is_string()) return v.get<std::string>();
  if (v.is_number_float()) {
    const double d = v.get<double>();
    return std::isfinite(d) && d == std::round(d) && std::fabs(d) < 1e15 ? std::to_string(static_cast<long long>(d))
                                                                          : num_text(v, 3);
  }
  if (v.is_boolean()) return v.get<bool>() ? "yes" : "no";
  if (v.is_null()) return "-";
  if (v.is_array() && std::all_of(v.begin(), v.end(), [](const json& x) { return x.is_primitive(); })) {
    std::string s;
    for (const auto& x : v) s += (s.empty() ? "" : " ") + value_text(x);
    return "[" + s + "]";
  }
  return v.dump();  // numbers that are integers, and nested objects
}

// "key value, key value": the detail of an event as a sentence of its fields.
std::string detail_text(const json& d) {
  if (!d.is_object()) return value_text(d);
  std::string s;
  for (const auto& [k, v] : d.items()) {
    if (!s.empty()) s += ", ";
    s += k + " " + value_text(v);
  }
  return s;
}

}  // namespace

Table events_table(const json& events) {
  Table t({"t_s", "kind", "detail"});
  for (const auto& e : events)
    t.add({e["t_s"].is_number() ? fixed(e["t_s"].get<double>(), 0) : "-", e.value("kind", "-"), detail_text(e["detail"])});
  return t;
}

}  // namespace fogbench::cli::commands
