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
  return v.dump();  // integers (and what detail_fields does not reach)
}

// "key value, key value": the detail of an event as a sentence of its fields; a nested object's
// fields as "outer.inner value", an array of objects as "key[i].field value".
void detail_fields(const json& d, const std::string& prefix, std::string& s) {
  auto add = [&](const std::string& k, const std::string& v) { s += (s.empty() ? "" : ", ") + k + " " + v; };
  if (d.is_object()) {
    for (const auto& [k, v] : d.items()) {
      const std::string key = prefix.empty() ? k : prefix + "." + k;
      if (v.is_object() || (v.is_array() && !v.empty() && !v.front().is_primitive())) detail_fields(v, key, s);
      else add(key, value_text(v));
    }
  } else if (d.is_array()) {
    for (std::size_t i = 0; i < d.size(); ++i) {
      const std::string key = prefix + "[" + std::to_string(i) + "]";
      if (d[i].is_structured()) detail_fields(d[i], key, s);
      else add(key, value_text(d[i]));
    }
  } else {
    add(prefix, value_text(d));
  }
}

std::string detail_text(const json& d) {
  if (!d.is_structured()) return value_text(d);
  std::string s;
  detail_fields(d, "", s);
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
